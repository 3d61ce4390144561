#include "RenderJob.h"
#include "ReferenceRendererGL.h"
#include "SyntheticScene.h"
#include "TestUtil.h"
#include "gl/GlContext.h"
#include "gl/GlDebug.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace seasonview;
using namespace seasonview::test;

namespace {

gl::GlContext* context() { return headlessContext(); }

std::vector<std::uint8_t> render(const Scene& scene, const Camera& cam, Season season, int w, int h,
                                 const ReferenceOptions& o = {}) {
    auto r = ReferenceRendererGL::create(scene, o);
    EXPECT_TRUE(r.ok()) << r.message();
    if (!r.ok()) return {};
    gl::RenderTarget t(w, h);
    (*r)->render(cam, season, t);
    EXPECT_EQ(gl::drainErrors(), "");
    return rgbOf(t.readRgba());
}

// A camera straight down whose frustum matches a w x h image of `gsd` metres per pixel exactly.
Camera exactTopDown(double w, double h, double gsd) {
    Camera c;
    c.pitchDeg = -90;
    c.position = {0, 0, (h * gsd * 0.5) / std::tan(30.0 * 3.14159265358979323846 / 180.0)};
    (void)w;
    return c;
}

} // namespace

TEST(ReferenceRendererGLTest, TopDownReproducesTheImageNorthUp) {
    ASSERT_TRUE(context());
    TempDir dir("ref-topdown");
    auto scene = writeTestPair(dir.path(), 64, 48, 0.5);
    ASSERT_TRUE(scene.ok()) << scene.message();
    const int errors = gl::debugErrorCount();
    for (Season season : {Season::LeafOn, Season::LeafOff}) {
        ReferenceOptions noAniso;
        noAniso.anisotropy = 1.0f;
        const auto img = render(*scene, exactTopDown(64, 48, 0.5), season, 64, 48, noAniso);
        auto src = readImageU8(season == Season::LeafOn ? dir / "on.tif" : dir / "off.tif", 3);
        ASSERT_TRUE(src.ok());
        const ImageDiff d = compareRgb(img, src->pixels, 64, 48, 3);
        // Pixel centres land on texel centres at one texel per pixel: the image comes back exactly (north up,
        // east right). Anisotropic filtering is off here because llvmpipe's blurs even at 1:1.
        EXPECT_LE(d.maxDelta, 1);
        EXPECT_LT(d.meanDelta, 0.05);
    }
    EXPECT_EQ(gl::debugErrorCount(), errors);
}

TEST(ReferenceRendererGLTest, SixteenBitIsStretched) {
    ASSERT_TRUE(context());
    TempDir dir("ref-16bit");
    auto scene = writeTestPair(dir.path(), 64, 48, 0.5, true);
    ASSERT_TRUE(scene.ok()) << scene.message();
    const auto img = render(*scene, exactTopDown(64, 48, 0.5), Season::LeafOn, 64, 48);
    ASSERT_FALSE(img.empty());
    // Values 300..2500 of 65535 would render nearly black unstretched; the 0.5-99.5 % stretch spans 0..255.
    int lo = 255, hi = 0;
    for (std::uint8_t v : img) {
        lo = std::min(lo, int(v));
        hi = std::max(hi, int(v));
    }
    EXPECT_LE(lo, 5);
    EXPECT_GE(hi, 250);
}

TEST(ReferenceRendererGLTest, TiledTexturesMatchOneTexture) {
    ASSERT_TRUE(context());
    TempDir dir("ref-tiled");
    auto scene = writeTestPair(dir.path(), 200, 150, 0.5);
    ASSERT_TRUE(scene.ok()) << scene.message();
    ReferenceOptions one;
    one.anisotropy = 1.0f;
    ReferenceOptions tiled = one;
    tiled.maxTextureSize = 64; // 4 x 3 layers of 62-pixel steps
    auto r = ReferenceRendererGL::create(*scene, tiled);
    ASSERT_TRUE(r.ok());
    EXPECT_EQ((*r)->stats().textureLayers, 12);
    // At one texel per pixel the seams between layers must be invisible.
    const Camera top = exactTopDown(200, 150, 0.5);
    const ImageDiff exact = compareRgb(render(*scene, top, Season::LeafOn, 200, 150, one),
                                       render(*scene, top, Season::LeafOn, 200, 150, tiled), 200, 150, 3);
    EXPECT_LE(exact.maxDelta, 1);
    // Oblique: far away, coarse mip levels of 64-texel layers differ from the whole image's (a real layer is
    // 16384 texels wide, so this only shows at tiny scales); the image must still agree closely.
    Camera cam;
    cam.position = {-10, -60, 35};
    cam.yawDeg = 15;
    cam.pitchDeg = -35;
    const ImageDiff d = compareRgb(render(*scene, cam, Season::LeafOn, 320, 240, one),
                                   render(*scene, cam, Season::LeafOn, 320, 240, tiled), 320, 240, 3);
    EXPECT_GT(d.psnr, 30.0);
    EXPECT_LT(d.meanDelta, 2.0);
}

TEST(ReferenceRendererGLTest, GoldenSyntheticSceneWithTerrain) {
    ASSERT_TRUE(context());
    TempDir dir("ref-golden");
    SynthOptions o;
    o.sizeM = 128;
    o.gsd = 0.5;
    o.seed = 7;
    auto rep = generateSyntheticScene(o, dir.path());
    ASSERT_TRUE(rep.ok()) << rep.message();
    auto src = parseManifest(dir / "scene.json");
    ASSERT_TRUE(src.ok()) << src.message();
    auto scene = loadScene(*src, dir / "cache");
    ASSERT_TRUE(scene.ok()) << scene.message();
    ASSERT_TRUE(scene->elevation);
    const Camera oblique = app::obliqueCamera(*scene, 30.0, -35.0);
    const auto img = render(*scene, oblique, Season::LeafOn, 320, 240);
    // llvmpipe is deterministic for a given Mesa/LLVM: the tolerance only absorbs a few edge pixels that a
    // different rasteriser build may cover differently (max) without hiding a wrong image (mean).
    compareWithGolden("reference_synth_oblique_leafon", img, 320, 240, 64, 0.6);
    const auto top = render(*scene, app::overviewCamera(*scene, 320.0 / 240.0), Season::LeafOff, 320, 240);
    compareWithGolden("reference_synth_top_leafoff", top, 320, 240, 64, 0.6);
    // The scene centre is terrain (no holes in the mesh), the top rows are sky.
    auto isSky = [&](const std::vector<std::uint8_t>& im, int x, int y) {
        const std::uint8_t* p = &im[(size_t(y) * 320 + size_t(x)) * 3];
        return std::abs(p[0] - int(kBackgroundColor.r * 255 + 0.5f)) <= 1 &&
               std::abs(p[1] - int(kBackgroundColor.g * 255 + 0.5f)) <= 1 &&
               std::abs(p[2] - int(kBackgroundColor.b * 255 + 0.5f)) <= 1;
    };
    int holes = 0;
    for (int y = 100; y < 200; ++y)
        for (int x = 110; x < 210; ++x) holes += isSky(img, x, y) ? 1 : 0;
    EXPECT_EQ(holes, 0);
    EXPECT_TRUE(isSky(img, 160, 0));
    EXPECT_FALSE(isSky(top, 160, 120));
}

TEST(ReferenceRendererGLTest, RealSentinelPairRendersStretched) {
    auto data = realDataDir();
    if (!data) GTEST_SKIP() << "real data not found (set SEASONVIEW_DATA or provide ../shared/data)";
    ASSERT_TRUE(context());
    TempDir dir("ref-real");
    SceneSources s;
    s.leafon = *data / "seasons/saclay_w/leafon_2017-08-29.tif";
    s.leafoff = *data / "seasons/saclay_w/leafoff_2016-03-15.tif";
    auto scene = loadScene(s, dir / "cache");
    ASSERT_TRUE(scene.ok()) << scene.message();
    // Geographic seasons are warped onto the UTM zone of their centre (31N, south of Paris).
    EXPECT_EQ(scene->grid.georef.crs.epsg(), 32631);
    EXPECT_TRUE(scene->frame.isTranslation());
    EXPECT_TRUE(scene->warped());
    EXPECT_NEAR(scene->gsd, 10.0, 3.0); // Sentinel-2: ~10 m
    auto pyramids = app::preparePyramids(*scene, dir / "cache");
    ASSERT_TRUE(pyramids.ok()) << pyramids.message();
    ReferenceOptions o;
    o.levelZero = app::levelZeroOf(*scene, *pyramids);
    // Straight down over the part both seasons cover (the grid's corners are the warp's bare collar).
    Camera cam = app::overviewCamera(*scene, 4.0 / 3.0);
    cam.position.z *= 0.6;
    const auto img = render(*scene, cam, Season::LeafOn, 400, 300, o);
    ASSERT_FALSE(img.empty());
    double mean = 0;
    int lo = 255, hi = 0;
    for (std::uint8_t v : img) {
        mean += v;
        lo = std::min(lo, int(v));
        hi = std::max(hi, int(v));
    }
    mean /= double(img.size());
    EXPECT_GT(mean, 50.0) << "stretched reflectance is not dark";
    EXPECT_LT(mean, 200.0);
    EXPECT_GT(hi - lo, 150) << "the stretch spans the display range";
    (void)writeImageAtomic(outputDir() / "real_saclay_leafon.png", img.data(), 400, 300, 3);
}
