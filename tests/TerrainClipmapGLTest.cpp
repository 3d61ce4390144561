// The geometry clipmap terrain (terrain/GeometryClipmapGL.h) drawn by the clipmap renderer.
#include "ClipmapGL.h"
#include "ClipmapTerrainRendererGL.h"
#include "DepthAccuracy.h"
#include "ElevationPyramid.h"
#include "ReferenceRendererGL.h"
#include "RenderJob.h"
#include "SyntheticScene.h"
#include "TestUtil.h"
#include "gl/GlContext.h"
#include "gl/GlDebug.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <map>
#include <optional>
#include <tuple>

using namespace seasonview;
using namespace seasonview::test;

namespace {

// A 512 m scene: imagery 512² at 1 m, a DEM of `demSamples`² over the same square from `height(x, y)` (metres,
// x east, y south in [0, 1]); NaN heights are holes.
Result<Scene> demScene(const std::filesystem::path& dir, int demSamples, const std::function<float(double, double)>& height) {
    writeTestImage(dir / "on.tif", 512, 512, testGeoref(1.0), false, 1);
    writeTestImage(dir / "off.tif", 512, 512, testGeoref(1.0), false, 2);
    std::vector<float> h(size_t(demSamples) * size_t(demSamples));
    for (int y = 0; y < demSamples; ++y)
        for (int x = 0; x < demSamples; ++x)
            h[size_t(y) * size_t(demSamples) + size_t(x)] =
                height((x + 0.5) / demSamples, (y + 0.5) / demSamples);
    if (auto st = writeGeoTiff(dir / "dem.tif", h.data(), SampleType::F32, demSamples, demSamples, 1,
                               testGeoref(512.0 / demSamples));
        !st)
        return st.error();
    SceneSources s;
    s.leafon = dir / "on.tif";
    s.leafoff = dir / "off.tif";
    s.elevation = dir / "dem.tif";
    return loadScene(s, dir / "cache");
}

struct Terrain {
    std::vector<ImagePyramid> pyramids;
    std::optional<ImagePyramid> elevation;
    std::unique_ptr<ClipmapGL> clip;
    std::unique_ptr<ClipmapTerrainRendererGL> renderer;
};

Terrain makeTerrain(const Scene& scene, const std::filesystem::path& cache, int n = 255, bool stitch = true) {
    Terrain t;
    auto p = app::preparePyramids(scene, cache);
    EXPECT_TRUE(p.ok()) << p.message();
    t.pyramids = std::move(*p);
    auto e = app::prepareElevation(scene, cache);
    EXPECT_TRUE(e.ok()) << e.message();
    t.elevation = std::move(*e);
    ClipmapOptions co;
    co.size = 256;
    auto c = ClipmapGL::create(t.pyramids, co);
    EXPECT_TRUE(c.ok()) << c.message();
    t.clip = std::move(*c);
    GeometryClipmapOptions go;
    go.n = n;
    go.stitchLevels = stitch;
    auto r = ClipmapTerrainRendererGL::create(scene, *t.clip, t.elevation ? &*t.elevation : nullptr, go);
    EXPECT_TRUE(r.ok()) << r.message();
    t.renderer = std::move(*r);
    return t;
}

void draw(const Scene& scene, Terrain& t, const Camera& cam, const ImagerySettings& s, const gl::RenderTarget& target) {
    const ClipmapGeometry g = app::clipmapGeometry(scene, t.clip->schedule().layout());
    t.clip->update(app::clipmapCentres(scene, cam, target.width(), target.height(), CenterPlacement::Footprint, g));
    t.clip->completeSynchronously();
    t.renderer->updateGeometry(cam, target.height());
    t.renderer->completeGeometry();
    t.renderer->render(cam, s, target);
}

// Sky pixels with terrain above them in the same column. A heightfield seen from above it has none: rays lower in
// a column hit the surface before higher ones do. Cracks between levels show up exactly as such pixels.
int skyBelowTerrain(const std::vector<float>& depth, int w, int h) {
    int holes = 0;
    for (int x = 0; x < w; ++x) {
        bool terrainAbove = false;
        for (int y = 0; y < h; ++y) {
            // Only the background (depth 0) is a hole. Depth 1 is the near plane, 5 cm from the eye: never terrain
            // seen from above it, nor background. llvmpipe draws one stray fragment there in some of these views
            // (15 m, yaw 0, 45 or 180 depending on the DEM's sampling): the levels view shows it comes from
            // level 5 / level 4 (32 / 16 m cells), whose triangles beside the camera span the eye plane and are
            // near-clipped; the fragment sits at the clipped vertex's depth, 1.0, six rows above where that
            // triangle really meets the horizon, and stays at the same pixel with the near plane at 1 m. It is a
            // clipping artefact of a huge triangle, not a gap between levels.
            const float d = depth[size_t(y) * size_t(w) + size_t(x)];
            const bool terrain = d > 0.0f && d < 0.999f;
            if (terrain) terrainAbove = true;
            else if (d == 0.0f && terrainAbove) ++holes;
        }
    }
    return holes;
}

int countSky(const std::vector<float>& depth) {
    return int(std::count(depth.begin(), depth.end(), 0.0f));
}

// Background pixels below terrain over 72 level, grazing views (pitch 0, yaw in 15 degree steps) of a spiky DEM,
// n = 31 so many level borders are in view. At pitch 0 every image column is a vertical plane, where a heightfield
// seen from above it can show the background only above its silhouette: any background pixel below terrain is a
// crack. The lower half of the (120 degree) view looks down at up to 60 degrees, so rays through a crack go under
// the surface and reach the background.
int cracksOnSpikyDem(bool stitch, int demSamples = 512) {
    TempDir dir("terrain-spiky");
    // Every DEM sample a random 0..6 m on bumps of 4 m period: neighbouring samples differ by metres, so every
    // coarser level's edge disagrees with its finer neighbour's odd vertices unless the levels are stitched.
    auto scene = demScene(dir.path(), demSamples, [demSamples](double x, double y) {
        const std::uint32_t k = std::uint32_t(x * demSamples) * 73856093u ^ std::uint32_t(y * demSamples) * 19349663u;
        const double bumps = 3.0 * std::sin(x * 512.0 * M_PI / 2.0) * std::sin(y * 512.0 * M_PI / 2.5);
        return float(bumps + double((k * 2654435761u >> 8) % 600u) / 100.0);
    });
    EXPECT_TRUE(scene.ok()) << scene.message();
    if (!scene) return -1;
    Terrain t = makeTerrain(*scene, dir / "cache", 31, stitch);
    const int w = 640, h = 480;
    gl::RenderTarget target(w, h);
    int cracks = 0;
    for (double yaw = 0.0; yaw < 360.0; yaw += 15.0)
        for (double z : {15.0, 40.0, 120.0}) {
            Camera cam;
            cam.position = {0.0, 0.0, z};
            cam.yawDeg = yaw;
            cam.pitchDeg = 0.0;
            cam.fovYDeg = 120.0;
            draw(*scene, t, cam, {}, target);
            const auto depth = target.readDepth();
            const int c = skyBelowTerrain(depth, w, h);
            if (c > 0) std::printf("yaw %.0f, %.0f m: %d crack pixels\n", yaw, z, c);
            cracks += c;
            EXPECT_GT(countSky(depth), 0); // the horizon is in view
            EXPECT_GE(t.renderer->geometry().levelCount() - t.renderer->geometry().placement().finest, 4);
        }
    EXPECT_EQ(gl::drainErrors(), "");
    return cracks;
}

} // namespace

TEST(TerrainClipmapGLTest, SpikyDemShowsNoCracksFromALowGrazingView) {
    ASSERT_TRUE(headlessContext());
    // None at all. (Stitching with a separate mesh of zero-area triangles beside the T-junctions left one pixel in
    // one of these views, where a pixel centre fell exactly on the seam; the outer edge now has no T-junction, see
    // GeometryClipmapLayoutTest.StitchedOuterEdgeIsTheCoarserLevelsEdge. 360 views in 5 degree steps at 15, 40, 100,
    // 120 and 140 m showed none either.)
    EXPECT_EQ(cracksOnSpikyDem(true), 0);
}

// A DEM 4x coarser than the imagery: the finest levels lie below the DEM's resolution, on its triangulated surface,
// and blend only where their coarser level is the DEM's own level 0.
TEST(TerrainClipmapGLTest, LevelsFinerThanTheDemShowNoCracks) {
    ASSERT_TRUE(headlessContext());
    EXPECT_EQ(cracksOnSpikyDem(true, 128), 0);
}

// The same views with the levels left unstitched (no transition blending, odd outer-edge vertices left where they
// are) must crack: the detector above sees real cracks.
TEST(TerrainClipmapGLTest, UnstitchedLevelsCrack) {
    ASSERT_TRUE(headlessContext());
    EXPECT_GT(cracksOnSpikyDem(false), 100);
}

// DEM holes (NaN) are filled when the DEM loads: the elevation pyramid holds no NaN and nothing spikes.
TEST(TerrainClipmapGLTest, NanHolesAreFilledNotSpikes) {
    ASSERT_TRUE(headlessContext());
    TempDir dir("terrain-nan");
    auto scene = demScene(dir.path(), 128, [](double x, double y) {
        if (std::abs(x - 0.5) < 0.1 && std::abs(y - 0.5) < 0.1) return std::numeric_limits<float>::quiet_NaN();
        return float(20.0 * std::sin(x * 6.0) + 10.0 * y);
    });
    ASSERT_TRUE(scene.ok()) << scene.message();
    EXPECT_GT(scene->elevation->filledSamples, 0);
    Terrain t = makeTerrain(*scene, dir / "cache");
    ASSERT_TRUE(t.elevation);
    for (const PyramidLevel& l : t.elevation->levels) {
        auto img = readImageF32(l.file, 1);
        ASSERT_TRUE(img.ok()) << img.message();
        for (float v : img->pixels) ASSERT_TRUE(std::isfinite(v) && v > -25.0f && v < 35.0f) << l.file << " " << v;
    }
    const int w = 160, h = 120;
    gl::RenderTarget target(w, h);
    const Camera cam = app::obliqueCamera(*scene, 0.0, -35.0, 0.6);
    draw(*scene, t, cam, {}, target);
    EXPECT_EQ(skyBelowTerrain(target.readDepth(), w, h), 0);
    EXPECT_EQ(gl::drainErrors(), "");
}

// Without a DEM the terrain is the flat plane at 0 m and matches the reference.
TEST(TerrainClipmapGLTest, FlatSceneStillRenders) {
    ASSERT_TRUE(headlessContext());
    TempDir dir("terrain-flat");
    auto scene = writeTestPair(dir.path(), 256, 192, 1.0);
    ASSERT_TRUE(scene.ok()) << scene.message();
    Terrain t = makeTerrain(*scene, dir / "cache");
    EXPECT_FALSE(t.elevation);
    const int w = 160, h = 120;
    gl::RenderTarget target(w, h);
    const Camera cam = app::obliqueCamera(*scene, 30.0, -40.0, 0.5);
    draw(*scene, t, cam, {}, target);
    const auto mine = rgbOf(target.readRgba());
    const auto mineDepth = target.readDepth();
    auto ref = ReferenceRendererGL::create(*scene);
    ASSERT_TRUE(ref.ok()) << ref.message();
    (*ref)->render(cam, Season::LeafOn, target);
    EXPECT_GE(compareRgb(mine, rgbOf(target.readRgba()), w, h, 3).psnr, 35.0);
    EXPECT_LT(compareDepth(target.readDepth(), mineDepth, w, h, kNearPlane).meanErrorPx, 0.05);
    EXPECT_EQ(gl::drainErrors(), "");
}

// The accuracy figures on a small synthetic scene with relief, 45 degrees down: mean depth difference
// <= 1 px against the full-resolution mesh, PSNR >= 35 dB; and the triangle count does not grow with the DEM.
TEST(TerrainClipmapGLTest, AccurateAgainstTheFullMeshAndConstantTriangles) {
    ASSERT_TRUE(headlessContext());
    const int w = 320, h = 180;
    gl::RenderTarget target(w, h);
    std::vector<std::int64_t> triangles;
    for (int samples : {64, 256, 2048}) { // 8 m (coarser than the mesh: upsampled levels), 2 m, 0.25 m over the same hills
        TempDir dir("terrain-acc");
        auto scene = demScene(dir.path(), samples, [](double x, double y) {
            return float(40.0 * std::sin(x * 7.0) * std::cos(y * 5.0) + 15.0 * std::sin((x + y) * 23.0));
        });
        ASSERT_TRUE(scene.ok()) << scene.message();
        Terrain t = makeTerrain(*scene, dir / "cache");
        const Camera cam = app::obliqueCamera(*scene, 20.0, -45.0, 0.5);
        // Isotropic filtering on both sides: this compares geometry, and llvmpipe's anisotropic sampler speckles
        // on steep slopes.
        ImagerySettings iso;
        iso.anisotropy = 1.0f;
        draw(*scene, t, cam, iso, target);
        triangles.push_back(t.renderer->triangles());
        const auto mine = rgbOf(target.readRgba());
        const auto mineDepth = target.readDepth();
        ReferenceOptions ro;
        ro.anisotropy = 1.0f;
        auto ref = ReferenceRendererGL::create(*scene, ro);
        ASSERT_TRUE(ref.ok()) << ref.message();
        (*ref)->render(cam, Season::LeafOn, target);
        const DepthAccuracy acc = compareDepth(target.readDepth(), mineDepth, w, h, kNearPlane);
        const auto theirs = rgbOf(target.readRgba());
        const double psnr = compareRgb(mine, theirs, w, h, 3).psnr;
        (void)writeImageAtomic(outputDir() / ("terrain_acc_" + std::to_string(samples) + ".png"), mine.data(), w, h, 3);
        (void)writeImageAtomic(outputDir() / ("terrain_acc_" + std::to_string(samples) + "_reference.png"), theirs.data(), w, h, 3);
        std::printf("DEM %d^2: mean depth error %.3f px (p95 %.3f), PSNR %.2f dB, %lld triangles (reference %lld)\n",
                    samples, acc.meanErrorPx, acc.p95ErrorPx, psnr, static_cast<long long>(triangles.back()),
                    static_cast<long long>((*ref)->stats().triangles));
        EXPECT_LE(acc.meanErrorPx, 1.0);
        // The 8 m DEM's reference mesh ends at its outermost sample centres, 4 m inside the imagery's edge, where
        // the clipmap goes on with the edge's heights: that strip on the silhouette, not the relief, keeps its PSNR
        // near 30 dB (its depth error is 0.01 px).
        if (samples >= 256) {
            EXPECT_GE(psnr, 35.0);
        }
        EXPECT_GT(acc.pixels, w * h / 2);
    }
    // The mesh follows the screen, not the DEM: levels finer than the 8 m DEM take its triangulated heights, so all
    // three draw the same levels in metres.
    EXPECT_GT(triangles[0], 10000);
    EXPECT_NEAR(double(triangles[1]) / double(triangles[0]), 1.0, 0.02);
    EXPECT_NEAR(double(triangles[2]) / double(triangles[0]), 1.0, 0.02);
    EXPECT_EQ(gl::drainErrors(), "");
}

// Golden images of the inspection views on the synthetic scene.
TEST(TerrainClipmapGLTest, GoldenWireframeAndLevels) {
    ASSERT_TRUE(headlessContext());
    TempDir dir("terrain-golden");
    SynthOptions o;
    o.sizeM = 512;
    o.gsd = 0.5;
    o.seed = 3;
    ASSERT_TRUE(generateSyntheticScene(o, dir.path()).ok());
    auto src = parseManifest(dir / "scene.json");
    ASSERT_TRUE(src.ok());
    auto scene = loadScene(*src, dir / "cache");
    ASSERT_TRUE(scene.ok()) << scene.message();
    Terrain t = makeTerrain(*scene, dir / "cache", 63);
    const int w = 320, h = 240;
    gl::RenderTarget target(w, h);
    const Camera cam = app::obliqueCamera(*scene, 20.0, -30.0, 0.3);
    for (auto [view, name] : {std::pair{ImageryView::Wireframe, "terrain_wireframe"}, std::pair{ImageryView::Levels, "terrain_levels"}}) {
        ImagerySettings s;
        s.view = view;
        draw(*scene, t, cam, s, target);
        // Lines and level borders move by a pixel between rasteriser builds (max); the mean catches a wrong layout.
        compareWithGolden(name, rgbOf(target.readRgba()), w, h, 255, 2.0);
    }
    EXPECT_EQ(gl::drainErrors(), "");
}

// auto shades the terrain as its renderer is fastest: deferred on a software rasteriser, forward on a GPU (wireframe
// and levels forward always); every name parses back.
TEST(TerrainClipmapGLTest, AutoShadingFollowsTheRenderer) {
    ASSERT_TRUE(headlessContext());
    for (TerrainShading t : {TerrainShading::Auto, TerrainShading::Forward, TerrainShading::Deferred})
        EXPECT_EQ(parseTerrainShading(terrainShadingName(t)), t);
    EXPECT_FALSE(parseTerrainShading("gpu"));
    const bool software = gl::isSoftwareRenderer(headlessContext()->info().renderer);
    EXPECT_EQ(resolveTerrainShading(TerrainShading::Auto), software ? TerrainShading::Deferred : TerrainShading::Forward);
    EXPECT_EQ(resolveTerrainShading(TerrainShading::Forward), TerrainShading::Forward);
    EXPECT_EQ(resolveTerrainShading(TerrainShading::Deferred), TerrainShading::Deferred);
    EXPECT_EQ(resolveTerrainShading(TerrainShading::Auto, headlessContext()->info().renderer),
              resolveTerrainShading(TerrainShading::Auto));
    EXPECT_EQ(resolveTerrainShading(TerrainShading::Auto, "NVIDIA H200/PCIe/SSE2"), TerrainShading::Forward);
    EXPECT_EQ(resolveTerrainShading(TerrainShading::Auto, "llvmpipe (LLVM 15.0.6, 256 bits)"), TerrainShading::Deferred);
    ImagerySettings s;
    EXPECT_EQ(s.path, TerrainShading::Auto);
    EXPECT_EQ(ClipmapTerrainRendererGL::resolvesDeferred(s), software);
    s.view = ImageryView::Wireframe;
    EXPECT_FALSE(ClipmapTerrainRendererGL::resolvesDeferred(s));
}

// Each view is its own program (VIEW and NORMALS are compile-time constants, shaders/common_view.glsl): every one
// compiles and draws, with and without shading, forward and deferred, both the same pixels (unshaded: bit for bit;
// shaded, the resolve rebuilds the normal's z from x and y: within one level); and the swipe view is the leaf-on
// view left of the divider and the leaf-off view right of it, pixel for pixel.
TEST(TerrainClipmapGLTest, EveryViewProgramDraws) {
    ASSERT_TRUE(headlessContext());
    TempDir dir("terrain-views");
    auto scene = demScene(dir.path(), 128, [](double x, double y) { return float(30.0 * std::sin(x * 6.0) * std::cos(y * 4.0)); });
    ASSERT_TRUE(scene.ok()) << scene.message();
    Terrain t = makeTerrain(*scene, dir / "cache", 63);
    const int w = 160, h = 120;
    gl::RenderTarget target(w, h);
    const Camera cam = app::obliqueCamera(*scene, 20.0, -40.0, 0.5);
    std::map<std::pair<int, bool>, std::vector<std::uint8_t>> images;
    for (ImageryView view : {ImageryView::LeafOn, ImageryView::LeafOff, ImageryView::Blend, ImageryView::Swipe,
                             ImageryView::Lod, ImageryView::Wireframe, ImageryView::Levels, ImageryView::Relief,
                             ImageryView::Canopy})
        for (bool shaded : {false, true}) {
            ImagerySettings s;
            s.view = view;
            s.shading = shaded ? 0.7f : 0.0f;
            s.path = TerrainShading::Forward;
            draw(*scene, t, cam, s, target);
            const auto forwardDepth = target.readDepth();
            const auto forward = rgbOf(target.readRgba());
            s.path = TerrainShading::Deferred;
            draw(*scene, t, cam, s, target);
            const auto depth = target.readDepth();
            const std::string name = std::string(imageryViewName(view)) + (shaded ? " shaded" : "");
            EXPECT_GT(std::count_if(depth.begin(), depth.end(), [](float d) { return d > 0.0f; }), w * h / 2) << name;
            EXPECT_EQ(depth, forwardDepth) << name;
            images[{int(view), shaded}] = rgbOf(target.readRgba());
            const auto& deferred = images[{int(view), shaded}];
            int maxDiff = 0;
            for (size_t i = 0; i < forward.size(); ++i) maxDiff = std::max(maxDiff, std::abs(int(forward[i]) - int(deferred[i])));
            EXPECT_LE(maxDiff, shaded || view == ImageryView::Relief ? 1 : 0) << name;
        }
    EXPECT_EQ(gl::drainErrors(), "");
    auto differ = [&](ImageryView a, ImageryView b, bool shaded) {
        return images.at({int(a), shaded}) != images.at({int(b), shaded});
    };
    EXPECT_TRUE(differ(ImageryView::LeafOn, ImageryView::LeafOff, false));
    EXPECT_TRUE(differ(ImageryView::LeafOn, ImageryView::Relief, false));
    EXPECT_NE(images.at({int(ImageryView::LeafOn), false}), images.at({int(ImageryView::LeafOn), true}));
    const auto& on = images.at({int(ImageryView::LeafOn), false});
    const auto& off = images.at({int(ImageryView::LeafOff), false});
    const auto& swipe = images.at({int(ImageryView::Swipe), false});
    int mismatched = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            if (std::abs(x + 0.5 - 0.5 * w) < 2.0) continue; // the divider
            const auto& expected = x < w / 2 ? on : off;
            for (int c = 0; c < 3; ++c) {
                const size_t i = (size_t(y) * size_t(w) + size_t(x)) * 3 + size_t(c);
                mismatched += swipe[i] != expected[i] ? 1 : 0;
            }
        }
    EXPECT_EQ(mismatched, 0);
}
