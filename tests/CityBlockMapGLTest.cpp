// The city in blockmap mode (city/CityRendererGL.h with city/BlockMapTraversal.h; Cignoni et al. 2007 §4): the atlas
// tree near, ray-cast BlockMaps far, switched by projected error. Against the atlas mode on a synthetic block city:
// the picture (PSNR over the city's pixels, at eight overviews too), the triangles and draw calls at an overview and at
// street level, the goldens of the overview and of the levels view (what drew each pixel).
#include "CityJob.h"
#include "CityDraw.h"
#include "CityRendererGL.h"
#include "Raster.h"
#include "Scene.h"
#include "TestUtil.h"
#include "gl/GlDebug.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <tuple>

using namespace seasonview;
using namespace seasonview::test;

namespace {

constexpr int kW = 320, kH = 240;

// PSNR over the pixels either image drew the city on (not the clear colour), and how many there were.
std::pair<double, std::size_t> cityPsnr(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b) {
    const std::uint8_t clear[3] = {51, 77, 102};
    auto background = [&](const std::vector<std::uint8_t>& p, std::size_t i) {
        for (int c = 0; c < 3; ++c)
            if (std::abs(int(p[i * 4 + std::size_t(c)]) - int(clear[c])) > 1) return false;
        return true;
    };
    double se = 0.0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < a.size() / 4; ++i) {
        if (background(a, i) && background(b, i)) continue;
        ++n;
        for (int c = 0; c < 3; ++c) {
            const double d = double(a[i * 4 + std::size_t(c)]) - double(b[i * 4 + std::size_t(c)]);
            se += d * d;
        }
    }
    if (n == 0) return {0.0, 0};
    const double mse = se / double(3 * n);
    return {mse > 0.0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : 99.0, n};
}

struct BlockCity {
    std::filesystem::path dir;
    std::string tree;
    std::optional<Scene> scene;
    BlockCity() {
        // 400 buildings on 50 blocks: about 400 × 380 m around the centre. Made once for all of this file's test
        // processes (the atlas tree and the BlockMaps take most of a test's time, under the sanitizers minutes).
        const auto shared = sharedFixture("city-blockmap", [](const std::filesystem::path& d) {
            const CliResult synth = runCli({"synth", "--out", (d / "s").string(), "--size-m", "512", "--gsd", "1",
                                            "--block-city", "400", "--facade-size", "64"});
            EXPECT_EQ(synth.exitCode, 0) << synth.err;
            const CliResult atlas = runCli({"atlas", "build", (d / "s/city/city.obj").string(), "--obj-local", "--out",
                                            (d / "t.svat").string(), "--atlas-size", "128"});
            EXPECT_EQ(atlas.exitCode, 0) << atlas.err;
            if (synth.exitCode != 0 || atlas.exitCode != 0) return false;
            // The pyramids and the BlockMaps into the cache, so that the tests find them made.
            auto sources = parseManifest(d / "s/scene.json");
            if (!sources.ok()) return false;
            auto s = loadScene(*sources, d / "cache");
            if (!s.ok()) return false;
            city::CitySettings cs;
            cs.mode = city::CityMode::BlockMap;
            const auto st = app::prepareCityBlockMaps(*s, (d / "t.svat").string(), d / "cache", cs);
            EXPECT_TRUE(st.ok()) << st.message();
            return st.ok();
        });
        if (!shared) {
            ADD_FAILURE() << "the block city could not be made";
            return;
        }
        dir = *shared;
        tree = (dir / "t.svat").string();
        auto sources = parseManifest(dir / "s/scene.json");
        EXPECT_TRUE(sources.ok()) << sources.message();
        auto s = loadScene(*sources, dir / "cache");
        EXPECT_TRUE(s.ok()) << s.message();
        if (s.ok()) scene = std::move(*s);
    }
    Camera camera(double x, double y, double above, double yaw, double pitch) const {
        Camera c;
        c.position = {x, y, scene->terrainHeight(x, y) + above};
        c.yawDeg = yaw;
        c.pitchDeg = pitch;
        c.fovYDeg = 60.0;
        return c;
    }
    city::CitySettings settings(city::CityMode mode) const {
        city::CitySettings cs;
        cs.mode = mode;
        cs.threaded = false;
        cs.occlusion = false;
        cs.capacityBytes = 1ull << 30;
        return cs;
    }
    std::unique_ptr<city::CityRendererGL> renderer(city::CitySettings cs) {
        if (auto st = app::prepareCityBlockMaps(*scene, tree, dir / "cache", cs); !st) {
            ADD_FAILURE() << st.message();
            return nullptr;
        }
        auto r = city::CityRendererGL::create(*scene, tree, cs);
        EXPECT_TRUE(r.ok()) << r.message();
        return r.ok() ? std::move(*r) : nullptr;
    }
};

BlockCity& blockCity() {
    static BlockCity c;
    return c;
}

// The block city's renderers in atlas mode and in blockmap mode.
std::pair<std::unique_ptr<city::CityRendererGL>, std::unique_ptr<city::CityRendererGL>> bothModes(BlockCity& bc) {
    return {bc.renderer(bc.settings(city::CityMode::Atlas)), bc.renderer(bc.settings(city::CityMode::BlockMap))};
}

// The block city drawn in atlas mode and in blockmap mode at one camera, everything loaded: both pictures, their
// frames' counters, and the PSNR over the city's pixels.
struct Compared {
    std::vector<std::uint8_t> atlas, blockmap;
    city::CityFrameStats sa, sb;
    double psnr = 0.0;
    std::size_t pixels = 0;
};
// RGBA of `w` × `h` box-filtered by k × k (the mean of each block, rounded).
std::vector<std::uint8_t> boxFiltered(const std::vector<std::uint8_t>& rgba, int w, int h, int k) {
    std::vector<std::uint8_t> out(std::size_t(w / k) * std::size_t(h / k) * 4);
    for (int y = 0; y < h / k; ++y)
        for (int x = 0; x < w / k; ++x)
            for (int c = 0; c < 4; ++c) {
                int sum = 0;
                for (int j = 0; j < k; ++j)
                    for (int i = 0; i < k; ++i)
                        sum += rgba[(std::size_t(y * k + j) * std::size_t(w) + std::size_t(x * k + i)) * 4 + std::size_t(c)];
                out[(std::size_t(y) * std::size_t(w / k) + std::size_t(x)) * 4 + std::size_t(c)] =
                    std::uint8_t((sum + k * k / 2) / (k * k));
            }
    return out;
}

// With `samples` k > 1 the target holds k × k samples a pixel (the renderers' error bounds k times larger, so they
// draw the output's levels of detail), box-filtered to kW × kH before they are compared.
Compared compareModes(city::CityRendererGL& atlas, city::CityRendererGL& blockmap, const Camera& cam,
                      const gl::RenderTarget& target, int samples = 1) {
    Compared c;
    atlas.complete(cam, kW * samples, kH * samples);
    blockmap.complete(cam, kW * samples, kH * samples);
    c.atlas = boxFiltered(drawCity(atlas, cam, target, c.sa), kW * samples, kH * samples, samples);
    c.blockmap = boxFiltered(drawCity(blockmap, cam, target, c.sb), kW * samples, kH * samples, samples);
    std::tie(c.psnr, c.pixels) = cityPsnr(c.atlas, c.blockmap);
    return c;
}

} // namespace

TEST(CityBlockMapGLTest, FarBlocksAreMapsAndThePictureIsTheAtlasModes) {
    ASSERT_TRUE(headlessContext());
    BlockCity& bc = blockCity();
    ASSERT_TRUE(bc.scene);
    auto [atlas, blockmap] = bothModes(bc);
    ASSERT_TRUE(atlas && blockmap);
    gl::RenderTarget target(kW, kH);
    // The overview: buildings 4-6 px wide, maps of 2-4 m texels (at most 1 px), the outlines and the 1 m streets
    // between buildings and the sloped roofs where they are (the texels' parts, second prisms and roof planes).
    // Above the street: the near blocks polygons, the far ones maps of 1 m texels, at the switch distance.
    struct View {
        const char* name;
        Camera cam;
        double minPsnr;
    };
    const View views[] = {
        {"overview", bc.camera(0.0, -350.0, 450.0, 0.0, -50.0), 29.5},
        {"street", bc.camera(0.0, -230.0, 40.0, 0.0, -12.0), 40.0},
    };
    for (const View& v : views) {
        SCOPED_TRACE(v.name);
        const Compared c = compareModes(*atlas, *blockmap, v.cam, target);
        const auto &a = c.atlas, &b = c.blockmap;
        const auto &sa = c.sa, &sb = c.sb;
        const double psnr = c.psnr;
        const std::size_t pixels = c.pixels;
        std::printf("%s: atlas %lld triangles %d calls, blockmap %lld triangles %d calls %d maps; PSNR %.1f dB over %zu px\n",
                    v.name, (long long)sa.triangles, sa.drawCalls, (long long)sb.triangles, sb.drawCalls, sb.blockMaps,
                    psnr, pixels);
        for (const auto& [img, mode] : {std::pair{&a, "atlas"}, {&b, "blockmap"}})
            (void)writeImageAtomic(outputDir() / (std::string("blockmap_") + v.name + "_" + mode + ".png"),
                                   rgbOf(*img).data(), kW, kH, 3);
        EXPECT_GT(pixels, std::size_t(kW * kH / 20)) << "the city is in view";
        EXPECT_GT(sb.blockMaps, 0);
        EXPECT_EQ(sb.blockMapsNotResident, 0);
        EXPECT_GE(psnr, v.minPsnr);
        if (std::string(v.name) == "overview") {
            EXPECT_LE(sb.triangles * 10, sa.triangles) << "at the overview at least 10x fewer triangles";
            EXPECT_LE(sb.drawCalls * 10, sa.drawCalls) << "at the overview at least 10x fewer draw calls";
            compareWithGolden("city_blockmap_overview", rgbOf(b), kW, kH, 255, 3.0);
        } else {
            EXPECT_GT(sb.triangles, 12 * sb.blockMaps) << "the near field is polygons";
            EXPECT_LT(sb.triangles, sa.triangles);
            // The levels view: what drew each pixel (atlas white, plain roofs dark grey, maps purple).
            blockmap->settings().view.sources = true;
            city::CityFrameStats sl;
            const auto levels = drawCity(*blockmap, v.cam, target, sl);
            blockmap->settings().view.sources = false;
            compareWithGolden("city_blockmap_levels", rgbOf(levels), kW, kH, 255, 3.0);
        }
    }
}

// The overview's PSNR from one camera turns on a hundred pixels whose outlines lie within centimetres of their
// centres; over eight overviews (four headings at 450 m, one at 650 m, two diagonals at 400 m, one at 300 m) a change
// to the maps shows as what it does to the picture, not to those pixels. The PSNR of them all together.
TEST(CityBlockMapGLTest, EightOverviewsAgainstTheAtlasMode) {
    ASSERT_TRUE(headlessContext());
    BlockCity& bc = blockCity();
    ASSERT_TRUE(bc.scene);
    auto [atlas, blockmap] = bothModes(bc);
    ASSERT_TRUE(atlas && blockmap);
    gl::RenderTarget target(kW, kH);
    const double cams[][5] = {{0, -350, 450, 0, -50},    {350, 0, 450, 270, -50},    {0, 350, 450, 180, -50},
                              {-350, 0, 450, 90, -50},   {0, -500, 650, 0, -50},     {250, -250, 400, 315, -55},
                              {-250, 250, 400, 135, -55}, {0, -250, 300, 0, -45}};
    double se = 0.0; // summed squared error over 255², as mean × pixels
    std::size_t pixels = 0;
    for (const auto& c : cams) {
        const Compared r = compareModes(*atlas, *blockmap, bc.camera(c[0], c[1], c[2], c[3], c[4]), target);
        EXPECT_GT(r.pixels, std::size_t(kW * kH / 20)) << "the city is in view";
        EXPECT_GT(r.sb.blockMaps, 0);
        se += std::pow(10.0, -r.psnr / 10.0) * double(r.pixels);
        pixels += r.pixels;
        std::printf("overview at %g, %g, +%g m heading %g: %.2f dB over %zu px, %d maps\n", c[0], c[1], c[2], c[3],
                    r.psnr, r.pixels, r.sb.blockMaps);
    }
    const double all = -10.0 * std::log10(se / double(pixels));
    std::printf("all eight: %.2f dB over %zu px\n", all, pixels);
    EXPECT_GE(all, 30.0) << "walls shaded by the walls they show, parts of their roofs' area, colours through the "
                            "atlases, roofs across ridges fitted, 16-bit heights (30.09 dB with 8 bits, 29.96 without "
                            "the fit, 29.7 from the original textures, 28.8 without the rest)";

    // Each overview antialiased: 4 × 4 samples a pixel, box-filtered, both modes at the levels of detail of the
    // output's pixels. What is left is what the maps show differently, not where a pixel's one sample falls on a
    // building a few pixels wide (the aliasing both modes share).
    city::CitySettings as = bc.settings(city::CityMode::Atlas), bs = bc.settings(city::CityMode::BlockMap);
    as.tpp = bs.tpp = 4.0;
    bs.blockMapErrorPx = 4.0;
    auto atlas4 = bc.renderer(as), blockmap4 = bc.renderer(bs);
    ASSERT_TRUE(atlas4 && blockmap4);
    gl::RenderTarget target4(kW * 4, kH * 4);
    for (const auto& c : cams) {
        const Compared r = compareModes(*atlas4, *blockmap4, bc.camera(c[0], c[1], c[2], c[3], c[4]), target4, 4);
        std::printf("overview at %g, %g, +%g m heading %g, 4x4 samples a pixel: %.2f dB over %zu px, %d maps\n", c[0],
                    c[1], c[2], c[3], r.psnr, r.pixels, r.sb.blockMaps);
        EXPECT_GE(r.psnr, 31.0) << "at every overview, antialiased";
        EXPECT_GT(r.sb.blockMaps, 0);
    }
}

// The maps seen at a grazing angle are tested for occlusion first (city/CityRendererGL.h, MapOcclusion): drawn each
// under conditional rendering, or after the answers are read in one instanced draw with the others. The same maps,
// in the same order, so the same pixels, frame after frame along a walk above the street (the first frame with
// nothing known, then the temporal answers); readback in fewer draw calls.
TEST(CityBlockMapGLTest, TestedMapsDrawTheSameReadBackOrConditional) {
    ASSERT_TRUE(headlessContext());
    BlockCity& bc = blockCity();
    ASSERT_TRUE(bc.scene);
    city::CitySettings cs = bc.settings(city::CityMode::BlockMap);
    cs.occlusion = true;
    cs.mapOcclusion = city::MapOcclusion::Conditional;
    auto conditional = bc.renderer(cs);
    cs.mapOcclusion = city::MapOcclusion::Readback;
    auto readback = bc.renderer(cs);
    ASSERT_TRUE(conditional && readback);
    EXPECT_EQ(readback->mapOcclusionUsed(), city::MapOcclusion::Readback);
    gl::RenderTarget target(kW, kH);
    int fewerCalls = 0;
    for (int f = 0; f < 4; ++f) {
        SCOPED_TRACE(f);
        const Camera cam = bc.camera(-20.0 + 12.0 * f, -240.0 + 8.0 * f, 30.0, 5.0 * f, -8.0);
        city::CityFrameStats sc, sr;
        conditional->complete(cam, kW, kH);
        readback->complete(cam, kW, kH);
        conditional->update(cam, kW, kH);
        readback->update(cam, kW, kH);
        const auto a = drawCity(*conditional, cam, target, sc);
        const auto b = drawCity(*readback, cam, target, sr);
        EXPECT_GT(sc.blockMaps, 0);
        EXPECT_EQ(sc.blockMaps, sr.blockMaps);
        EXPECT_EQ(sc.occlusionQueries, sr.occlusionQueries);
        std::printf("frame %d: %d maps, %d queries; draw calls %d conditional, %d readback\n", f, sc.blockMaps,
                    sc.occlusionQueries, sc.drawCalls, sr.drawCalls);
        EXPECT_TRUE(a == b) << "the tested maps drew differently";
        EXPECT_LE(sr.drawCalls, sc.drawCalls);
        fewerCalls += sr.drawCalls < sc.drawCalls;
    }
    EXPECT_GT(fewerCalls, 0) << "maps were tested (drawn one by one under conditional rendering)";
}

// Maps loading: their buildings are drawn with polygons meanwhile, and with the atlases the atlas mode would draw
// them with as those arrive (the pager asks for the atlases of what the drawn maps do not cover, not of what the
// maps the view wants will cover), not with the root's alone. Once every map is in, the picture is the still's.
TEST(CityBlockMapGLTest, PolygonsStandingInForLoadingMapsGetTheirAtlases) {
    ASSERT_TRUE(headlessContext());
    BlockCity& bc = blockCity();
    ASSERT_TRUE(bc.scene);
    gl::RenderTarget target(kW, kH);
    const Camera overview = bc.camera(0.0, -350.0, 450.0, 0.0, -50.0);
    city::CitySettings cs = bc.settings(city::CityMode::BlockMap);
    cs.uploadBytesPerFrame = 1; // one block a frame
    auto loading = bc.renderer(cs);
    auto still = bc.renderer(bc.settings(city::CityMode::BlockMap));
    ASSERT_TRUE(loading && still);
    still->complete(overview, kW, kH);
    city::CityFrameStats st;
    const auto expected = drawCity(*still, overview, target, st);
    int framesLoading = 0, mostAtlasesWhileLoading = 0, frame = 0;
    for (; frame < 2000; ++frame) {
        loading->update(overview, kW, kH);
        drawCity(*loading, overview, target, st);
        if (st.blockMapsNotResident == 0 && st.loaderQueue == 0 && frame > 0) break;
        if (st.blockMapsNotResident > 0) {
            ++framesLoading;
            mostAtlasesWhileLoading = std::max(mostAtlasesWhileLoading, st.textureBinds);
        }
    }
    auto atlas = bc.renderer(bc.settings(city::CityMode::Atlas));
    ASSERT_TRUE(atlas);
    atlas->complete(overview, kW, kH);
    city::CityFrameStats sa;
    drawCity(*atlas, overview, target, sa);
    std::printf("%d frames to load the overview, %d of them with maps missing; at most %d textures bound meanwhile "
                "(the atlas mode's still: %d)\n", frame, framesLoading, mostAtlasesWhileLoading, sa.textureBinds);
    EXPECT_GT(framesLoading, 10);
    EXPECT_GT(mostAtlasesWhileLoading, 1) << "polygons standing in for maps drawn with atlases below the root";
    const auto loaded = drawCity(*loading, overview, target, st);
    EXPECT_EQ(st.blockMapsNotResident, 0);
    EXPECT_TRUE(loaded == expected) << "once loaded, the picture is the still's";
}

// Pops: along a descent from the overview to above the street, each frame drawn with the last frame's switches
// (polygons to maps, map to finer maps; CitySettings::holdSwitches) and with its own: what changes between the two is
// what the viewer sees pop at that frame. At the default error bound of 1 px the worst is a map level switch at the
// overview (33.2 dB over the city's pixels, 0.4 % of the picture changed by more than 16 levels).
TEST(CityBlockMapGLTest, SwitchesAtTheDefaultErrorDoNotPop) {
    ASSERT_TRUE(headlessContext());
    BlockCity& bc = blockCity();
    ASSERT_TRUE(bc.scene);
    auto blockmap = bc.renderer(bc.settings(city::CityMode::BlockMap));
    ASSERT_TRUE(blockmap);
    gl::RenderTarget target(kW, kH);
    const Camera from = bc.camera(0.0, -350.0, 450.0, 0.0, -50.0), to = bc.camera(0.0, -230.0, 40.0, 0.0, -12.0);
    constexpr int kFrames = 40;
    double worst = 99.0;
    std::size_t switched = 0, worstPixels = 0;
    for (int i = 0; i <= kFrames; ++i) {
        const double t = double(i) / kFrames;
        Camera c = to;
        c.position = from.position + (to.position - from.position) * t;
        c.pitchDeg = from.pitchDeg + (to.pitchDeg - from.pitchDeg) * t;
        blockmap->complete(c, kW, kH);
        city::CityFrameStats held, now;
        blockmap->settings().holdSwitches = true;
        const auto before = drawCity(*blockmap, c, target, held);
        blockmap->settings().holdSwitches = false;
        const auto after = drawCity(*blockmap, c, target, now);
        if (held.blockMaps == now.blockMaps && held.triangles == now.triangles) continue; // no switch this frame
        ++switched;
        std::size_t changed = 0;
        for (std::size_t p = 0; p < before.size(); p += 4)
            changed += std::abs(int(before[p]) - int(after[p])) + std::abs(int(before[p + 1]) - int(after[p + 1])) +
                           std::abs(int(before[p + 2]) - int(after[p + 2])) > 48;
        const double psnr = cityPsnr(before, after).first;
        if (psnr < worst) {
            worst = psnr;
            worstPixels = changed;
            for (const auto& [img, when] : {std::pair{&before, "before"}, {&after, "after"}})
                (void)writeImageAtomic(outputDir() / (std::string("blockmap_pop_") + when + ".png"),
                                       rgbOf(*img).data(), kW, kH, 3);
        }
    }
    std::printf("%zu of %d frames switched; worst pop: PSNR %.1f dB over the city, %zu px changed by more than 16 levels "
                "per channel (of %d)\n", switched, kFrames + 1, worst, worstPixels, kW * kH);
    EXPECT_GT(switched, 5u) << "the descent switches polygons and maps";
    EXPECT_GE(worst, 30.0);
    EXPECT_LT(worstPixels, std::size_t(kW * kH * 3 / 100)) << "under 3 % of the picture changes visibly at a switch";
}

// The pager's capacity with maps and atlases in it: each view's blocks fit, both views' do not; along a walk from one
// to the other and back, the blocks the pager counts hold at most the capacity, and so does the GL side with the maps'
// pool's free room; maps and atlases are
// evicted and loaded again, and the first view then draws what it drew at first and what an ample renderer draws.
TEST(CityBlockMapGLTest, PagerCapacityHoldsWithMapsAndAtlases) {
    ASSERT_TRUE(headlessContext());
    BlockCity& bc = blockCity();
    ASSERT_TRUE(bc.scene);
    gl::RenderTarget target(kW, kH);
    const Camera a = bc.camera(-150.0, -230.0, 40.0, 30.0, -12.0), b = bc.camera(150.0, 230.0, 40.0, 210.0, -12.0);
    city::CityFrameStats st;
    std::uint64_t bytesA = 0, bytesB = 0, both = 0;
    std::vector<std::uint8_t> ampleA;
    {
        auto ample = bc.renderer(bc.settings(city::CityMode::BlockMap));
        ASSERT_TRUE(ample);
        ample->complete(a, kW, kH);
        ampleA = drawCity(*ample, a, target, st);
        bytesA = st.residentBytes;
        EXPECT_GT(st.blockMaps, 0);
        ample->complete(b, kW, kH);
        drawCity(*ample, b, target, st);
        both = st.residentBytes;
    }
    {
        auto ample = bc.renderer(bc.settings(city::CityMode::BlockMap));
        ASSERT_TRUE(ample);
        ample->complete(b, kW, kH);
        drawCity(*ample, b, target, st);
        bytesB = st.residentBytes;
    }
    city::CitySettings cs = bc.settings(city::CityMode::BlockMap);
    cs.capacityBytes = std::max(bytesA, bytesB) + std::max(bytesA, bytesB) / 20;
    std::printf("A %llu B %llu both %llu bytes, capacity %llu\n", (unsigned long long)bytesA, (unsigned long long)bytesB,
                (unsigned long long)both, (unsigned long long)cs.capacityBytes);
    ASSERT_GT(both, cs.capacityBytes) << "the two views together must not fit";
    cs.uploadBytesPerFrame = 1u << 20;
    auto tight = bc.renderer(cs);
    ASSERT_TRUE(tight);
    tight->complete(a, kW, kH);
    const auto firstA = drawCity(*tight, a, target, st);
    EXPECT_TRUE(firstA == ampleA) << "A with the tight capacity is A";
    std::size_t evicted = 0, standIns = 0;
    std::uint64_t mostAllocated = 0;
    auto walk = [&](const Camera& from, const Camera& to) {
        for (int i = 1; i <= 12; ++i) {
            const double t = i / 12.0;
            Camera c = to;
            c.position = from.position + (to.position - from.position) * t;
            c.yawDeg = from.yawDeg + (to.yawDeg - from.yawDeg) * t;
            tight->update(c, kW, kH);
            drawCity(*tight, c, target, st);
            evicted += st.evictedBlocks;
            standIns += std::size_t(st.blockMapsNotResident + st.coarserThanWanted);
            EXPECT_LE(st.residentBytes, cs.capacityBytes) << "frame " << i;
            // The GL side: what the pager counts and the maps' pool's free room, within the capacity too.
            EXPECT_GE(st.allocatedBytes, st.residentBytes) << "frame " << i;
            EXPECT_LE(st.allocatedBytes, cs.capacityBytes) << "frame " << i;
            mostAllocated = std::max(mostAllocated, st.allocatedBytes);
        }
    };
    walk(a, b);
    walk(b, a);
    tight->complete(a, kW, kH);
    const auto againA = drawCity(*tight, a, target, st);
    std::printf("walk: %zu blocks evicted, %zu frames' nodes drawn with a stand-in while theirs loaded; the GL side at "
                "most %llu bytes\n", evicted, standIns, (unsigned long long)mostAllocated);
    EXPECT_GT(evicted, 10u) << "the walk evicted blocks";
    EXPECT_LE(st.residentBytes, cs.capacityBytes);
    EXPECT_TRUE(againA == firstA) << "A after the walk is A again";
}
