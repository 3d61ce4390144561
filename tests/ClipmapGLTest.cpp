#include "ClipmapGL.h"
#include "ClipmapTerrainRendererGL.h"
#include "RenderJob.h"
#include "ReferenceRendererGL.h"
#include "SyntheticScene.h"
#include "TestUtil.h"
#include "gl/GlContext.h"
#include "gl/GlDebug.h"

#include <gtest/gtest.h>

#include <atomic>
#include <optional>
#include <chrono>
#include <thread>

using namespace seasonview;
using namespace seasonview::test;

namespace {

gl::GlContext* context() { return headlessContext(); }

std::vector<std::uint8_t> rgbOf(const gl::RenderTarget& t) { return test::rgbOf(t.readRgba()); }

// One synthetic scene (512 m at 0.25 m = 2048² per season) shared by the tests of this file.
struct SceneFixture {
    TempDir dir{"clipmap-gl"};
    Scene scene;
    std::vector<ImagePyramid> pyramids;
    std::optional<ImagePyramid> elevation;
    SceneFixture() {
        SynthOptions o;
        o.sizeM = 512;
        o.gsd = 0.25;
        o.seed = 3;
        auto rep = generateSyntheticScene(o, dir.path());
        EXPECT_TRUE(rep.ok()) << rep.message();
        auto src = parseManifest(dir / "scene.json");
        auto s = loadScene(*src, dir / "cache");
        EXPECT_TRUE(s.ok()) << s.message();
        scene = std::move(*s);
        auto p = app::preparePyramids(scene, dir / "cache");
        EXPECT_TRUE(p.ok()) << p.message();
        pyramids = std::move(*p);
        auto e = app::prepareElevation(scene, dir / "cache");
        EXPECT_TRUE(e.ok()) << e.message();
        elevation = std::move(*e);
    }
};

SceneFixture& fixture() {
    static SceneFixture f;
    return f;
}

ClipmapOptions smallClipmap() {
    ClipmapOptions o;
    o.size = 256; // 2048² image: levels 0..2 toroidal (2048, 1024, 512), 256 and below resident
    return o;
}

// A source that takes its time: proves that frames never wait and that missing blocks fall back to coarser levels.
class SlowPyramidSource final : public BlockSource {
public:
    // Reads wait while the gate is closed, then take `delayMs` each.
    SlowPyramidSource(const std::vector<ImagePyramid>& p, int delayMs, std::shared_ptr<std::atomic<bool>> gate)
        : m_inner(std::make_unique<PyramidBlockSource>(pyramidLevelFiles(p), 64)), m_delay(delayMs),
          m_gate(std::move(gate)) {}
    int layers() const override { return m_inner->layers(); }
    Status read(int layer, int level, const TexelRect& t, std::uint8_t* rgba) override {
        while (!m_gate->load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
        std::this_thread::sleep_for(std::chrono::milliseconds(m_delay));
        return m_inner->read(layer, level, t, rgba);
    }

private:
    std::unique_ptr<PyramidBlockSource> m_inner;
    int m_delay;
    std::shared_ptr<std::atomic<bool>> m_gate;
};

} // namespace

TEST(ClipmapGLTest, MatchesTheReferenceRenderer) {
    ASSERT_TRUE(context());
    SceneFixture& f = fixture();
    ASSERT_EQ(f.pyramids.size(), 2u);
    auto reference = ReferenceRendererGL::create(f.scene);
    ASSERT_TRUE(reference.ok()) << reference.message();
    auto clip = ClipmapGL::create(f.pyramids, smallClipmap());
    ASSERT_TRUE(clip.ok()) << clip.message();
    EXPECT_EQ((*clip)->schedule().layout().clipLevels(), 3);
    auto renderer = ClipmapTerrainRendererGL::create(f.scene, **clip, f.elevation ? &*f.elevation : nullptr);
    ASSERT_TRUE(renderer.ok()) << renderer.message();
    const int w = 320, h = 240;
    gl::RenderTarget target(w, h);
    const ClipmapGeometry geometry = app::clipmapGeometry(f.scene, (*clip)->schedule().layout());
    struct Case {
        const char* name;
        Camera camera;
        double minPsnr;
    };
    // Straight down, low enough that the scene's edge is out of view: at the edge of the world single pixels flip
    // between terrain and sky wherever the LOD geometry's heights differ from the full mesh by a fraction of a pixel.
    Camera top = app::overviewCamera(f.scene, double(w) / h);
    top.position.z *= 0.75;
    Camera oblique = app::obliqueCamera(f.scene, 20.0, -30.0, 0.3);
    // Thresholds from the issue: top-down >= 40 dB, 60 degrees off nadir >= 35 dB.
    for (const Case& c : {Case{"top", top, 40.0}, Case{"oblique", oblique, 35.0}}) {
        (*clip)->update(app::clipmapCentres(f.scene, c.camera, w, h, CenterPlacement::Footprint, geometry));
        (*clip)->completeSynchronously();
        (*renderer)->updateGeometry(c.camera, target.height());
        (*renderer)->completeGeometry();
        (*renderer)->render(c.camera, {}, target);
        const auto mine = rgbOf(target);
        (*reference)->render(c.camera, Season::LeafOn, target);
        const auto ref = rgbOf(target);
        const ImageDiff d = compareRgb(mine, ref, w, h, 3);
        EXPECT_GE(d.psnr, c.minPsnr) << c.name;
        std::printf("%s: PSNR %.2f dB vs the reference\n", c.name, d.psnr);
        (void)writeImageAtomic(outputDir() / (std::string("clipmap_") + c.name + ".png"), mine.data(), w, h, 3);
    }
    EXPECT_EQ(gl::drainErrors(), "");
}

namespace {
// Box-filters an RGB image down by an integer factor: a supersampled image is the ground truth for filtering.
std::vector<std::uint8_t> boxDown(const std::vector<std::uint8_t>& rgb, int w, int h, int k) {
    const int ow = w / k, oh = h / k;
    std::vector<std::uint8_t> out(size_t(ow) * size_t(oh) * 3);
    for (int y = 0; y < oh; ++y)
        for (int x = 0; x < ow; ++x)
            for (int c = 0; c < 3; ++c) {
                int sum = 0;
                for (int j = 0; j < k; ++j)
                    for (int i = 0; i < k; ++i) sum += rgb[(size_t(y * k + j) * size_t(w) + size_t(x * k + i)) * 3 + size_t(c)];
                out[(size_t(y) * size_t(ow) + size_t(x)) * 3 + size_t(c)] = std::uint8_t((sum + k * k / 2) / (k * k));
            }
    return out;
}
} // namespace

// At a grazing angle the isotropic level (from the footprint's long axis) blurs across the view; the footprint
// filter must come clearly closer to an 8x8-supersampled reference.
TEST(ClipmapGLTest, AnisotropicFilterApproachesSupersampling) {
    ASSERT_TRUE(context());
    SceneFixture& f = fixture();
    ReferenceOptions iso;
    iso.anisotropy = 1.0f;
    auto reference = ReferenceRendererGL::create(f.scene, iso);
    ASSERT_TRUE(reference.ok()) << reference.message();
    auto clip = ClipmapGL::create(f.pyramids, smallClipmap());
    ASSERT_TRUE(clip.ok()) << clip.message();
    auto renderer = ClipmapTerrainRendererGL::create(f.scene, **clip, f.elevation ? &*f.elevation : nullptr);
    ASSERT_TRUE(renderer.ok()) << renderer.message();
    const int w = 160, h = 120, k = 8;
    const Camera cam = app::obliqueCamera(f.scene, 20.0, -15.0, 0.3);
    gl::RenderTarget big(w * k, h * k), target(w, h);
    (*reference)->render(cam, Season::LeafOn, big);
    const auto truth = boxDown(rgbOf(big), w * k, h * k, k);
    const ClipmapGeometry geometry = app::clipmapGeometry(f.scene, (*clip)->schedule().layout());
    (*clip)->update(app::clipmapCentres(f.scene, cam, w, h, CenterPlacement::Footprint, geometry));
    (*clip)->completeSynchronously();
    double psnr[2] = {0, 0};
    for (int i = 0; i < 2; ++i) {
        ImagerySettings s;
        s.anisotropy = i == 0 ? 1.0f : 8.0f;
        (*renderer)->updateGeometry(cam, target.height());
        (*renderer)->completeGeometry();
        (*renderer)->render(cam, s, target);
        psnr[i] = compareRgb(rgbOf(target), truth, w, h, 3).psnr;
    }
    std::printf("vs 8x8 supersampled: isotropic %.2f dB, anisotropic (8) %.2f dB\n", psnr[0], psnr[1]);
    EXPECT_GT(psnr[1], psnr[0] + 2.0);
    EXPECT_EQ(gl::drainErrors(), "");
}

TEST(ClipmapGLTest, GoldenLodView) {
    ASSERT_TRUE(context());
    SceneFixture& f = fixture();
    auto clip = ClipmapGL::create(f.pyramids, smallClipmap());
    ASSERT_TRUE(clip.ok()) << clip.message();
    auto renderer = ClipmapTerrainRendererGL::create(f.scene, **clip, f.elevation ? &*f.elevation : nullptr);
    ASSERT_TRUE(renderer.ok());
    const int w = 320, h = 240;
    gl::RenderTarget target(w, h);
    const Camera cam = app::obliqueCamera(f.scene, 20.0, -30.0, 0.3);
    (*clip)->update(app::clipmapCentres(f.scene, cam, w, h, CenterPlacement::Offset,
                                        app::clipmapGeometry(f.scene, (*clip)->schedule().layout())));
    (*clip)->completeSynchronously();
    ImagerySettings lod;
    lod.view = ImageryView::Lod;
    lod.anisotropy = 1.0f; // the isotropic levels, as in the paper's Fig. 2 (anisotropy moves used levels finer)
    (*renderer)->updateGeometry(cam, target.height());
    (*renderer)->completeGeometry();
    (*renderer)->render(cam, lod, target);
    // Level borders move by a pixel between rasteriser builds (max); the mean keeps a wrong layout visible.
    compareWithGolden("clipmap_lod_offset", rgbOf(target), w, h, 255, 1.0);
    EXPECT_EQ(gl::drainErrors(), "");
}

TEST(ClipmapGLTest, SlowSourceFallsBackAndRespectsTheBudget) {
    ASSERT_TRUE(context());
    SceneFixture& f = fixture();
    ClipmapOptions o = smallClipmap();
    o.uploadBudgetTexels = 2 * 64 * 64; // two blocks per frame
    auto gate = std::make_shared<std::atomic<bool>>(false); // the disk is stuck until we open it
    auto clip = ClipmapGL::create(f.pyramids, o, std::make_unique<SlowPyramidSource>(f.pyramids, 2, gate));
    ASSERT_TRUE(clip.ok()) << clip.message();
    auto renderer = ClipmapTerrainRendererGL::create(f.scene, **clip, f.elevation ? &*f.elevation : nullptr);
    ASSERT_TRUE(renderer.ok());
    const int w = 320, h = 240;
    gl::RenderTarget target(w, h), scratch(w, h);
    Camera cam; // 30 m above the ground, straight down: ~0.15 m per pixel, so level 0 is needed everywhere
    cam.position = {10.0, -20.0, f.scene.terrainHeight(10.0, -20.0) + 30.0};
    cam.pitchDeg = -90.0;
    const auto centres = app::clipmapCentres(f.scene, cam, w, h, CenterPlacement::Concentric,
                                             app::clipmapGeometry(f.scene, (*clip)->schedule().layout()));
    // A frame with every read stuck still completes (were update() to wait for the disk, this would hang).
    const ClipmapFrameStats first = (*clip)->update(centres);
    EXPECT_GT(first.blocksMissing, 10);
    EXPECT_EQ(first.blocksUploaded, 0);
    // Nothing loaded yet: everything comes from the resident coarse pyramid, and the frame is complete.
    (*renderer)->updateGeometry(cam, target.height());
    (*renderer)->completeGeometry();
    (*renderer)->render(cam, {}, target);
    const FrameLevelStats before = (*renderer)->measureLevels(cam, scratch);
    EXPECT_GT(before.terrainPixels, 10000);
    EXPECT_LT(before.coverage, 0.05);
    EXPECT_GT(before.meanLevelDeficit, 1.0);
    const auto coarse = rgbOf(target);
    for (size_t i = 0; i + 2 < coarse.size(); i += 3)
        ASSERT_FALSE(coarse[i] == 0 && coarse[i + 1] == 0 && coarse[i + 2] == 0) << "no unloaded (zero) texels drawn";
    // The disk recovers; frames go on; each uploads at most the budget (per layer: the budget counts both seasons).
    gate->store(true);
    int frames = 0;
    std::int64_t maxUpload = 0;
    ClipmapFrameStats s;
    do {
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
        s = (*clip)->update(centres);
        maxUpload = std::max(maxUpload, s.texelsUploaded);
        ++frames;
    } while (s.blocksMissing > 0 && frames < 2000);
    EXPECT_EQ(s.blocksMissing, 0);
    EXPECT_LE(maxUpload, 2 * o.uploadBudgetTexels);
    EXPECT_GT(frames, 20) << "the budget spread the uploads over many frames";
    const FrameLevelStats after = (*renderer)->measureLevels(cam, scratch);
    EXPECT_GT(after.coverage, 0.95);
    EXPECT_EQ(gl::drainErrors(), "");
}

TEST(ClipmapGLTest, ResidentMemoryDoesNotDependOnTheView) {
    ASSERT_TRUE(context());
    SceneFixture& f = fixture();
    auto clip = ClipmapGL::create(f.pyramids, smallClipmap());
    ASSERT_TRUE(clip.ok());
    const std::int64_t bytes = (*clip)->residentBytes();
    // 2 layers x (3 levels x 256² x 4 B + 256² x 4 B x 4/3) + tags (4² x 4 B x 3).
    EXPECT_EQ(bytes, 2 * (3 * 256 * 256 * 4 + 256 * 256 * 4 * 4 / 3) + 4 * 4 * 4 * 3);
    const ClipmapGeometry g = app::clipmapGeometry(f.scene, (*clip)->schedule().layout());
    for (double x : {-200.0, 0.0, 150.0}) {
        Camera c = app::obliqueCamera(f.scene, x, -40.0, 0.2);
        (*clip)->update(app::clipmapCentres(f.scene, c, 320, 240, CenterPlacement::Offset, g));
        (*clip)->completeSynchronously();
        EXPECT_EQ((*clip)->residentBytes(), bytes);
    }
}

// A fixed stack depth: the same bytes as a larger image that needs every level (--clip-levels).
TEST(ClipmapGLTest, FixedStackDepthGivesTheSameMemoryForEveryImage) {
    ASSERT_TRUE(context());
    SceneFixture& f = fixture();
    ClipmapOptions o = smallClipmap();
    o.minClipLevels = 5; // this 2048² image needs 3 levels of 256²; an 8192² image would need 5
    auto clip = ClipmapGL::create(f.pyramids, o);
    ASSERT_TRUE(clip.ok());
    EXPECT_EQ((*clip)->schedule().layout().clipLevels(), 3);
    EXPECT_EQ((*clip)->residentBytes(), 2 * (5 * 256 * 256 * 4 + 256 * 256 * 4 * 4 / 3) + 4 * 4 * 4 * 5);
    (*clip)->update(app::clipmapCentres(f.scene, app::overviewCamera(f.scene, 1.0), 256, 256, CenterPlacement::Concentric,
                                        app::clipmapGeometry(f.scene, (*clip)->schedule().layout())));
    (*clip)->completeSynchronously();
    EXPECT_EQ(gl::drainErrors(), "");
}
