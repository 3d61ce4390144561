// BlockMaps ray-cast on the GPU (city/BlockMapGL.h, shaders/blockmap.frag) against the CPU traversal they copy
// (city/BlockMap.h, traceBlockMap) pixel by pixel, and against the polygons they were built from: the depth a
// BlockMap writes is the depth its prisms' own faces give, so it composes with everything drawn around it.
#include "BlockMapGL.h"
#include "PrismCity.h"
#include "TerrainMeshGL.h"
#include "TestUtil.h"

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <numeric>
#include <glm/mat4x4.hpp>

using namespace seasonview;
using namespace seasonview::city;
using namespace seasonview::test;

namespace {

using test::Prism;

// Buildings of different heights, touching, a courtyard, and one standing higher than the block's floor (two texels
// of street around it), on 1 m texels, heights on the 0.1 m grid of 25.5 m.
const std::vector<Prism> kPrisms = {{2, 2, 14, 14, 25.5}, {14, 2, 26, 14, 12.3}, {2, 16, 9, 30, 7.0},
                                    {17, 17, 30, 20, 18.8}, {17, 27, 30, 30, 18.8}, {17, 20, 20, 27, 18.8},
                                    {27, 20, 30, 27, 18.8}, {11, 22, 15, 29, 14.2, 6.0}};
// The same with their outlines between the texels' edges, on sixteenths of a texel, and the two buildings that touch
// apart by a street of 3/8 of a texel inside texel column 14: the prisms stand on parts of their outer texels
// (BlockMap::rect), and texel column 14 holds two (BlockMap::rect2, height2).
const std::vector<Prism> kOffGrid = {{2.25, 2.5, 14.125, 13.75, 25.5}, {14.5, 2.5, 25.75, 13.75, 12.3},
                                     {2.375, 16.25, 9.5, 29.625, 7.0}, {17.5, 17.25, 29.75, 20, 18.8},
                                     {17.5, 27, 29.75, 29.5, 18.8}, {17.5, 20, 20.25, 27, 18.8},
                                     {27.25, 20, 29.75, 27, 18.8}, {11.25, 22.5, 15.0, 28.75, 14.2, 6.0}};

CityModel modelOf(const std::vector<Prism>& prisms) { return test::prismModel(prisms); }

// Sloped roofs (each texel's top the plane of its roof normal): a gabled building along x (eaves 10 m, ridge 15 m)
// and a shed roof rising along y (6 to 12 m), off the grid, untextured.
CityModel slopedModel() {
    CityModel m;
    test::addSlopedBuilding(m, 3.25, 4.5, 27.5, 16.0, 10.0, 15.0, true);
    test::addSlopedBuilding(m, 6.5, 19.5, 24.25, 29.75, 6.0, 12.0, false);
    return m;
}

BlockMap blockMapOf(glm::dvec2 origin, CityModel model) {
    for (TexturedTriangle& t : model.triangles)
        for (glm::dvec3& v : t.v) v += glm::dvec3(origin, 0.0);
    BlockMapOptions o;
    o.size = 32;
    o.wallTexels = 8;
    auto m = buildBlockMap(model, origin, 32.0, o, [](std::size_t, const glm::dvec3&) { return glm::dvec3(0.7); });
    EXPECT_TRUE(m) << m.message();
    return *m;
}

BlockMap blockMap(glm::dvec2 origin, const std::vector<Prism>& prisms) { return blockMapOf(origin, modelOf(prisms)); }

// Cameras around and above the block (local metres), looking at it.
std::vector<Camera> cameras(glm::dvec2 origin) {
    std::vector<Camera> out;
    for (const auto& [x, y, z, yaw, pitch] : {std::array<double, 5>{-20, -25, 40, 40, -35}, {60, 10, 25, -80, -20},
                                              {16, -30, 70, 0, -60}, {45, 50, 12, 220, -8}}) {
        Camera c;
        c.position = glm::dvec3(origin + glm::dvec2(x, y), z);
        c.yawDeg = yaw;
        c.pitchDeg = pitch;
        c.fovYDeg = 60.0;
        out.push_back(c);
    }
    return out;
}

constexpr int kW = 160, kH = 120;

glm::dmat4 viewProjOf(const Camera& c) { return c.projectionMatrix(double(kW) / kH, kNearPlane) * c.viewMatrix(); }

} // namespace

TEST(BlockMapGLTest, GpuRayCastingMatchesTheCpuTraversal) {
    ASSERT_TRUE(headlessContext());
    const glm::dvec2 origin(1000.0, -500.0); // away from the frame's origin, as blocks of a city are
    const std::pair<const char*, CityModel> blocks[] = {
        {"on the grid", modelOf(kPrisms)}, {"off the grid", modelOf(kOffGrid)}, {"sloped roofs", slopedModel()}};
    for (const auto& [name, model] : blocks) {
        SCOPED_TRACE(name);
        const BlockMap map = blockMapOf(origin, model);
        auto gpu = BlockMapGL::create(map);
        ASSERT_TRUE(gpu) << gpu.message();
        gl::RenderTarget target(kW, kH);
        int roofs = 0, walls = 0, mismatched = 0, compared = 0;
        for (const Camera& cam : cameras(origin)) {
            target.bind();
            beginTerrainPass(0.0f, 0.0f, 0.0f, 0.0f);
            BlockMapGL::DrawSettings s;
            s.outputKind = true;
            (*gpu)->draw(cam, target, s);
            const auto rgba = target.readRgba();
            const auto depth = target.readDepth();
            const glm::dmat4 vp = viewProjOf(cam), inv = glm::inverse(vp);
            for (int y = 0; y < kH; ++y)
                for (int x = 0; x < kW; ++x) {
                    const glm::dvec4 ndc((x + 0.5) / kW * 2.0 - 1.0, 1.0 - (y + 0.5) / kH * 2.0, 0.5, 1.0);
                    const glm::dvec4 w = inv * ndc;
                    const glm::dvec3 dir = glm::normalize(glm::dvec3(w) / w.w - cam.position);
                    const BlockMapHit h = traceBlockMap(map, cam.position, dir);
                    const std::size_t i = std::size_t(y) * kW + std::size_t(x);
                    const int gpuKind = rgba[i * 4] == 0 ? 0 : rgba[i * 4] < 192 ? 1 : 2; // 0.5: roof, 1: wall
                    ++compared;
                    if (gpuKind != int(h.kind)) {
                        ++mismatched;
                        continue;
                    }
                    if (h.kind == BlockMapHit::Kind::None) continue;
                    roofs += h.kind == BlockMapHit::Kind::Roof;
                    walls += h.kind == BlockMapHit::Kind::Wall;
                    const glm::dvec4 clip = vp * glm::dvec4(h.point, 1.0);
                    const double expected = clip.z / clip.w;
                    EXPECT_NEAR(depth[i], expected, 2e-4 * expected) << x << "," << y;
                }
        }
        // Float on the GPU, double on the CPU: a ray grazing a texel's edge may go either way.
        std::printf("%s: %d of %d pixels hit something else on the GPU\n", name, mismatched, compared);
        EXPECT_LT(mismatched, compared / 200) << mismatched << " of " << compared;
        EXPECT_GT(roofs, 1500);
        EXPECT_GT(walls, 1000);
    }
}

TEST(BlockMapGLTest, DepthIsThePolygonsDepth) {
    ASSERT_TRUE(headlessContext());
    for (const auto* prisms : {&kPrisms, &kOffGrid}) {
        SCOPED_TRACE(prisms == &kPrisms ? "on the grid" : "off the grid");
        const glm::dvec2 origin(-300.0, 200.0);
        const BlockMap map = blockMap(origin, *prisms);
        auto gpu = BlockMapGL::create(map);
        ASSERT_TRUE(gpu) << gpu.message();
        auto boxes = gl::ShaderProgram::build("city_box.vert", "city_box.frag");
        ASSERT_TRUE(boxes) << boxes.message();
        // The unit cube's 36 corners, as blockmap.vert spells them.
        const int corner[36] = {0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
                                2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};
        std::vector<glm::vec3> cube;
        for (int c : corner) cube.push_back(glm::vec3(float(c & 1), float((c >> 1) & 1), float((c >> 2) & 1)));
        gl::Buffer vbo = gl::Buffer::create();
        glNamedBufferStorage(vbo.id(), GLsizeiptr(cube.size() * sizeof(glm::vec3)), cube.data(), 0);
        gl::VertexArray vao = gl::VertexArray::create();
        glVertexArrayVertexBuffer(vao.id(), 0, vbo.id(), 0, sizeof(glm::vec3));
        glEnableVertexArrayAttrib(vao.id(), 0);
        glVertexArrayAttribFormat(vao.id(), 0, 3, GL_FLOAT, GL_FALSE, 0);
        glVertexArrayAttribBinding(vao.id(), 0, 0);

        gl::RenderTarget polygons(kW, kH), blocks(kW, kH);
        int both = 0, disagree = 0, covered = 0, farApart = 0;
        for (const Camera& cam : cameras(origin)) {
            polygons.bind();
            beginTerrainPass(0.0f, 0.0f, 0.0f, 0.0f);
            boxes->set("uViewProj", glm::mat4(viewProjOf(cam)));
            boxes->use();
            glBindVertexArray(vao.id());
            for (const Prism& p : *prisms) {
                boxes->set("uBoxMin", glm::vec3(glm::dvec3(origin.x + p.x0, origin.y + p.y0, p.base)));
                boxes->set("uBoxMax", glm::vec3(glm::dvec3(origin.x + p.x1, origin.y + p.y1, p.top)));
                glDrawArrays(GL_TRIANGLES, 0, 36);
            }
            glBindVertexArray(0);
            blocks.bind();
            beginTerrainPass(0.0f, 0.0f, 0.0f, 0.0f);
            (*gpu)->draw(cam, blocks);
            const auto a = polygons.readDepth(), b = blocks.readDepth();
            for (std::size_t i = 0; i < a.size(); ++i) {
                covered += a[i] > 0.0f;
                if ((a[i] > 0.0f) != (b[i] > 0.0f)) {
                    ++disagree;
                    continue;
                }
                if (a[i] <= 0.0f) continue;
                ++both;
                farApart += std::abs(b[i] - a[i]) > 2e-4f * a[i];
            }
        }
        EXPECT_GT(covered, 4 * kW * kH / 10);
        // Rasterised edges against ray-cast ones: pixel centres on a face's very edge may fall either side.
        std::printf("%s: %d of %d pixels covered by one and not the other, %d of %d at another depth\n",
                    prisms == &kPrisms ? "on the grid" : "off the grid", disagree, covered, farApart, both);
        EXPECT_LT(disagree, covered / 100) << disagree << " of " << covered;
        // Where both drew, the same depth (a few pixels on an edge show the roof in one and the wall under it in the
        // other).
        EXPECT_LT(farApart, both / 500) << farApart << " of " << both;
    }
}

// Wall colours reach the screen from the right column, also with 1,024 colours per column (a column's span past
// 2,000 words of the pool's buffer): each side of a box in its own colour, every wall pixel the CPU traversal says
// shows a side is that side's colour shaded by the side, mixed towards the next column along the wall as
// blockmap.frag interpolates (next to a corner, the corner's column: the mean of its two sides); a corner's, its
// column's colour so mixed, shaded by the side the ray came in by.
TEST(BlockMapGLTest, WallPixelsShowTheirSidesColours) {
    ASSERT_TRUE(headlessContext());
    const std::vector<Prism> box = {{6, 8, 26, 20, 25.5}};
    std::vector<int> faceOf;
    const CityModel model = test::prismModel(box, &faceOf);
    const glm::dvec3 colours[5] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 0}, {0.5, 0.5, 0.5}}; // -x, +x, -y, +y, roof
    BlockMapOptions o;
    o.size = 32;
    o.wallTexels = 1024;
    auto map = buildBlockMap(model, {0.0, 0.0}, 32.0, o,
                             [&](std::size_t tri, const glm::dvec3&) { return colours[faceOf[tri]]; });
    ASSERT_TRUE(map) << map.message();
    ASSERT_GT(map->columns(), 40);
    auto gpu = BlockMapGL::create(*map);
    ASSERT_TRUE(gpu) << gpu.message();
    gl::RenderTarget target(kW, kH);
    int checked = 0, wrong = 0, corners = 0, wrongCorners = 0;
    const glm::dvec3 sun = glm::normalize(glm::dvec3(-0.5, 0.6, 0.75)); // BlockMapGL::draw's
    for (const Camera& cam : cameras({0.0, 0.0})) {
        target.bind();
        beginTerrainPass(0.0f, 0.0f, 0.0f, 0.0f);
        (*gpu)->draw(cam, target);
        const auto rgba = target.readRgba();
        const glm::dmat4 inv = glm::inverse(viewProjOf(cam));
        for (int y = 0; y < kH; ++y)
            for (int x = 0; x < kW; ++x) {
                const glm::dvec4 w = inv * glm::dvec4((x + 0.5) / kW * 2.0 - 1.0, 1.0 - (y + 0.5) / kH * 2.0, 0.5, 1.0);
                const BlockMapHit h = traceBlockMap(*map, cam.position, glm::normalize(glm::dvec3(w) / w.w - cam.position));
                if (h.kind != BlockMapHit::Kind::Wall) continue;
                const std::uint32_t c = map->column[std::size_t(h.texel.y) * 32 + std::size_t(h.texel.x)];
                const glm::vec3 n = map->wallNormal[c - 1];
                const std::uint8_t* p = &rgba[(std::size_t(y) * kW + std::size_t(x)) * 4];
                const glm::ivec3 got(p[0], p[1], p[2]);
                // The colour along the wall: linear between the texel's column and the next texel's along the side
                // the ray came in by, the one the hit is nearer to, where that texel's same side is a wall at this
                // height (blockmap.frag). Each side is one colour, so any texel of a column is its colour.
                const auto columnColour = [&](std::uint32_t column) {
                    const std::uint8_t* q = &map->wallRgba[std::size_t(column - 1) * std::size_t(o.wallTexels) * 4];
                    return glm::dvec3(q[0], q[1], q[2]);
                };
                glm::dvec3 colour = columnColour(c);
                const int along = std::abs(h.normal.x) > 0.5 ? 1 : 0;
                const double f = h.point[along] / map->texel - double(h.texel[along]) - 0.5;
                glm::ivec2 next = h.texel;
                next[along] += f < 0.0 ? -1 : 1;
                const auto at = [&](glm::ivec2 t) { return std::size_t(t.y) * 32 + std::size_t(t.x); };
                const auto inside = [](glm::ivec2 t) { return t.x >= 0 && t.y >= 0 && t.x < 32 && t.y < 32; };
                const auto topOf = [&](std::uint16_t v) { return map->metresOf(v); };
                if (inside(next) && map->column[at(next)] != 0 && topOf(map->height[at(next)]) >= h.point.z) {
                    const glm::ivec2 front = next + glm::ivec2(glm::round(glm::dvec2(h.normal)));
                    if (!inside(front) || map->height[at(front)] == 0 || topOf(map->height[at(front)]) < h.point.z)
                        colour = glm::mix(colour, columnColour(map->column[at(next)]), std::abs(f));
                }
                if (std::abs(n.x) > 0.01f && std::abs(n.y) > 0.01f) {
                    // A corner texel's column averages its two sides' colours; its walls are on the grid, so the
                    // pixel is shaded by the side its ray came in by (the polygons' face), not by the mean normal.
                    EXPECT_EQ(map->wallOnGrid[c - 1], 1);
                    const double shade = 0.62 + 0.38 * std::abs(glm::dot(h.normal, sun));
                    bool ok = true;
                    for (int i = 0; i < 3; ++i) ok = ok && std::abs(got[i] - colour[i] * shade) < 6.0;
                    ++corners;
                    wrongCorners += !ok;
                    continue;
                }
                // A side's own colour (next to a corner, mixed with the corner's column), shaded by the side.
                const int side = n.x < -0.5f ? 0 : n.x > 0.5f ? 1 : n.y < -0.5f ? 2 : 3;
                EXPECT_EQ(columnColour(c), glm::round(colours[side] * 255.0));
                const double shade = 0.62 + 0.38 * std::abs(glm::dot(h.normal, sun));
                bool ok = true;
                for (int i = 0; i < 3; ++i) ok = ok && std::abs(got[i] - colour[i] * shade) < 6.0;
                ++checked;
                wrong += !ok;
            }
    }
    EXPECT_GT(checked, 1000);
    EXPECT_LT(wrong, checked / 200) << wrong << " of " << checked;
    EXPECT_GT(corners, 20);
    EXPECT_LT(wrongCorners, corners / 20 + 1) << wrongCorners << " of " << corners;
}

// A pool of many maps (BlockMapPoolGL): more than a layer of tiles and more walls than its first buffer, half the
// maps taken out (the words repacked into less) and others put in their slots and freed word ranges; any set of them drawn as one instanced draw is pixel for
// pixel the same picture as each map drawn alone into the same target.
TEST(BlockMapGLTest, PoolDrawsManyMapsInOneDrawAsEachAlone) {
    ASSERT_TRUE(headlessContext());
    // Two different blocks, copies of them on a grid of 40 m.
    const BlockMap a = blockMap({0.0, 0.0}, kOffGrid);
    BlockMap b = a;
    std::reverse(b.height.begin(), b.height.end()); // another block: the same prisms turned half a turn
    std::reverse(b.distance.begin(), b.distance.end());
    std::reverse(b.column.begin(), b.column.end());
    std::reverse(b.roofNormal.begin(), b.roofNormal.end());
    std::reverse(b.foot.begin(), b.foot.end());
    auto copyAt = [&](int i) {
        BlockMap m = i % 3 == 0 ? b : a;
        m.origin = glm::dvec2(40.0 * (i % 20), 40.0 * (i / 20));
        m.zTop = a.zTop + 0.5 * (i % 4); // heights differ by copy
        return m;
    };
    auto program = BlockMapPoolGL::buildProgram(false);
    ASSERT_TRUE(program) << program.message();
    BlockMapPoolGL pool(a.size);
    std::vector<int> handles;
    int mostSegments = 0;
    for (int i = 0; i < 300; ++i) {
        auto h = pool.add(copyAt(i));
        ASSERT_TRUE(h) << h.message();
        handles.push_back(*h);
        mostSegments = std::max({mostSegments, pool.tileSegments(), pool.pageSegments()});
        // Growing adds segments and copies nothing resident, until there are kMaxSegments of a kind (then merged).
        if (mostSegments < BlockMapPoolGL::kMaxSegments) {
            EXPECT_EQ(pool.movedBytes(), 0u) << "map " << i;
        }
        EXPECT_LE(pool.tileSegments(), BlockMapPoolGL::kMaxSegments);
        EXPECT_LE(pool.pageSegments(), BlockMapPoolGL::kMaxSegments);
    }
    EXPECT_EQ(mostSegments, BlockMapPoolGL::kMaxSegments) << "the test covers several segments";
    // The maps' words span pages (a page table in use), and the pool's use is what the pager counts for them.
    const std::size_t wordsA = packBlockMap(a).words.size(), wordsB = packBlockMap(b).words.size();
    ASSERT_GT(wordsA, kBlockMapPageWords) << "the test needs maps of several pages";
    auto counted = [&](int i) {
        return std::uint64_t(a.size) * std::uint64_t(a.size) * 16 + // four words a texel
               std::uint64_t(blockMapPages(i % 3 == 0 ? wordsB : wordsA)) * kBlockMapPageWords * 4;
    };
    std::uint64_t sum = 0;
    for (int i = 0; i < 300; ++i) sum += counted(i);
    EXPECT_EQ(pool.usedBytes(), sum);
    EXPECT_LE(pool.usedBytes(), pool.allocatedBytes());
    // Maps replaced by others of the same sizes take the pages freed, wherever they lie: nothing grows.
    const std::uint64_t full = pool.allocatedBytes();
    for (int i = 0; i < 30; i += 3) pool.remove(handles[std::size_t(i)]);
    for (int i = 0; i < 30; i += 3) {
        auto h = pool.add(copyAt(i));
        ASSERT_TRUE(h) << h.message();
        handles[std::size_t(i)] = *h;
    }
    EXPECT_EQ(pool.allocatedBytes(), full);
    for (int i = 0; i < 300; i += 2) pool.remove(handles[std::size_t(i)]);
    EXPECT_EQ(pool.maps(), 150u);
    for (int frame = 0; frame < BlockMapPoolGL::kShrinkAfterFrames; ++frame)
        ASSERT_TRUE(pool.prepare(~std::uint64_t(0), 0, 0));
    EXPECT_LT(pool.allocatedBytes(), full) << "half the maps gone: segments given back, their live maps moved";
    for (int i = 0; i < 300; i += 2) { // back, in freed slots and ranges, as other copies
        auto h = pool.add(copyAt((i + 7) % 300));
        ASSERT_TRUE(h) << h.message();
        handles[std::size_t(i)] = *h;
    }
    auto shown = [&](int i) { return i % 2 == 0 ? copyAt((i + 7) % 300) : copyAt(i); };
    // A pool refuses a map of another size with one line.
    BlockMapOptions small;
    small.size = 16;
    auto other = buildBlockMap(modelOf(kPrisms), {0.0, 0.0}, 32.0, small,
                               [](std::size_t, const glm::dvec3&) { return glm::dvec3(0.5); });
    ASSERT_TRUE(other) << other.message();
    auto refused = pool.add(*other);
    ASSERT_FALSE(refused);
    EXPECT_NE(refused.message().find("16"), std::string::npos) << refused.message();

    Camera cam;
    cam.position = glm::dvec3(200.0, -150.0, 260.0);
    cam.yawDeg = 0.0;
    cam.pitchDeg = -45.0;
    cam.fovYDeg = 60.0;
    const int W = 320, H = 240;
    const glm::dmat4 vp = cam.projectionMatrix(double(W) / H, kNearPlane) * cam.viewMatrix();
    const double pixelAngle = 2.0 * std::tan(cam.fovYDeg * M_PI / 360.0) / double(H);
    // Each picture: the maps `which` drawn into a cleared target, by `draw`.
    auto picture = [&](const std::function<void(gl::RenderTarget&)>& draw) {
        gl::RenderTarget t(W, H);
        t.bind();
        beginTerrainPass(0.0f, 0.0f, 0.0f, 0.0f);
        draw(t);
        return std::make_pair(t.readRgba(), t.readDepth());
    };
    auto poolDraw = [&](const std::vector<int>& which, bool oneByOne) {
        return picture([&](gl::RenderTarget&) {
            std::vector<BlockMapPoolGL::Instance> in;
            for (int i : which) in.push_back({handles[std::size_t(i)], glm::vec4(0.0f)});
            pool.setInstances(in);
            pool.begin(*program, vp, cam.position, pixelAngle, {}, false);
            if (oneByOne)
                for (int k = 0; k < int(in.size()); ++k) pool.draw(*program, k, 1);
            else
                pool.draw(*program, 0, int(in.size()));
            BlockMapPoolGL::end();
        });
    };
    auto compare = [&](const auto& x, const auto& y, const char* what) {
        int differ = 0, covered = 0;
        for (std::size_t i = 0; i < x.second.size(); ++i) {
            covered += x.second[i] > 0.0f;
            differ += x.second[i] != y.second[i] || x.first[i * 4] != y.first[i * 4] ||
                      x.first[i * 4 + 1] != y.first[i * 4 + 1] || x.first[i * 4 + 2] != y.first[i * 4 + 2];
        }
        EXPECT_EQ(differ, 0) << what << ": " << differ << " of " << covered << " pixels";
        return covered;
    };
    std::vector<int> every(300);
    std::iota(every.begin(), every.end(), 0);
    const auto batch = poolDraw(every, false);
    EXPECT_GT(compare(batch, poolDraw(every, true), "one draw against a draw per map"), W * H / 8);
    // The maps `which` each drawn from a pool of its own.
    auto eachOwn = [&](const std::vector<int>& which) {
        return picture([&](gl::RenderTarget& t) {
            for (int i : which) {
                auto g = BlockMapGL::create(shown(i));
                ASSERT_TRUE(g) << g.message();
                (*g)->draw(cam, t);
            }
        });
    };
    // Maps in reused slots and pages against each in a pool of its own.
    const std::vector<int> some = {0, 2, 3, 150, 151, 298, 299};
    EXPECT_GT(compare(poolDraw(some, false), eachOwn(some), "the pool's against each map's own"), W * H / 50);

    // Two thirds of the maps gone: once that has lasted kShrinkAfterFrames frames (not after a brief dip), the pool
    // gives back what it no longer needs, the live tiles moved into fewer layers, the pages in use below a new end;
    // the maps draw as before.
    const std::uint64_t before = pool.allocatedBytes();
    for (int i = 0; i < 300; ++i)
        if (i % 3 != 0) pool.remove(handles[std::size_t(i)]);
    for (int frame = 1; frame < BlockMapPoolGL::kShrinkAfterFrames; ++frame) {
        ASSERT_TRUE(pool.prepare(~std::uint64_t(0), 0, 0));
        EXPECT_EQ(pool.allocatedBytes(), before) << "frame " << frame;
    }
    const std::uint64_t moved = pool.movedBytes(), live = pool.usedBytes();
    ASSERT_TRUE(pool.prepare(~std::uint64_t(0), 0, 0));
    EXPECT_LT(pool.allocatedBytes(), before / 2);
    EXPECT_LE(pool.movedBytes() - moved, live) << "only maps of the segments given back are copied, each once";
    const std::vector<int> kept = {0, 3, 6, 150, 153, 294, 297};
    EXPECT_GT(compare(poolDraw(kept, false), eachOwn(kept), "the pool's after it shrank"), W * H / 50);
}

TEST(BlockMapGLTest, PoolGrowsWithinItsByteLimit) {
    ASSERT_TRUE(headlessContext());
    const BlockMap a = blockMap({0.0, 0.0}, kOffGrid);
    const std::uint64_t tile = std::uint64_t(a.size) * std::uint64_t(a.size) * 16, // four words a texel
                        pages = std::uint64_t(blockMapPages(packBlockMap(a).words.size())) * kBlockMapPageWords * 4,
                        one = tile + pages;
    // What the maps need: their tiles and pages. A map's pages lie in one segment, so past the limit each segment may
    // keep fewer free pages than a map takes: at most a map's pages a segment.
    auto needed = [&](int maps) {
        return std::uint64_t(maps) * one + std::uint64_t(BlockMapPoolGL::kMaxSegments) * (pages - kBlockMapPageWords * 4);
    };
    // Free room only within the limit, never less than the maps need: the limit of 100 maps, then none.
    for (const std::uint64_t limit : {100 * one, std::uint64_t(0)}) {
        BlockMapPoolGL pool(a.size);
        pool.setByteLimit(limit);
        std::uint64_t most = 0;
        for (int i = 0; i < 300; ++i) {
            auto h = pool.add(a);
            ASSERT_TRUE(h) << h.message();
            EXPECT_EQ(pool.usedBytes(), std::uint64_t(i + 1) * one);
            EXPECT_LE(pool.allocatedBytes(), std::max(limit, needed(i + 1))) << "map " << i << ", limit " << limit;
            most = std::max(most, pool.allocatedBytes() - pool.usedBytes());
            EXPECT_LE(pool.tileSegments(), BlockMapPoolGL::kMaxSegments);
            EXPECT_LE(pool.pageSegments(), BlockMapPoolGL::kMaxSegments);
        }
        // Past the limit every growth is a segment of what the map needs: at kMaxSegments the two least used are merged
        // (the maps copied), and the maps draw from wherever they went (PoolDrawsManyMapsInOneDrawAsEachAlone).
        if (limit == 0) {
            EXPECT_GT(pool.movedBytes(), 0u);
        }
        std::printf("limit %llu B: at most %llu B free room (a map %llu B)\n", (unsigned long long)limit,
                    (unsigned long long)most, (unsigned long long)one);
    }
    // With no limit the pool keeps room to grow into (an eighth more pages, a quarter more layers).
    BlockMapPoolGL free(a.size);
    for (int i = 0; i < 300; ++i) ASSERT_TRUE(free.add(a));
    EXPECT_GT(free.allocatedBytes(), free.usedBytes());
}
