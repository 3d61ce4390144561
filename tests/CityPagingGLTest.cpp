// Paging on the GL side (city/CityRendererGL.h with city/AtlasPager.h, thesis §4.6): original textures paged in bands
// of rows are evicted under a tight capacity and uploaded again, band by band, and then draw exactly what they drew
// the first time and what a renderer that never evicts draws; the GL texture storage held never exceeds the
// capacity, a split texture counted whole from its first band on. In atlas mode (originals at leaves nearer than
// dmin) and original mode.
#include "CityDraw.h"
#include "CityRendererGL.h"
#include "Raster.h"
#include "Scene.h"
#include "TestUtil.h"
#include "gl/GlDebug.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>

using namespace seasonview;
using namespace seasonview::test;

TEST(CityPagingGLTest, SplitOriginalsEvictedAndUploadedAgainDrawAsBefore) {
    ASSERT_TRUE(headlessContext());
    TempDir dir("city-paging");
    // 40 buildings with 128² facades; with 64² atlases each facade (RGBA8 + mips, 5.3 atlases) is paged in 6 bands.
    const CliResult synth = runCli({"synth", "--out", (dir / "s").string(), "--size-m", "256", "--gsd", "1",
                                    "--block-city", "40", "--facade-size", "128"});
    ASSERT_EQ(synth.exitCode, 0) << synth.err;
    EXPECT_NE(synth.out.find(" 40 buildings"), std::string::npos) << synth.out;
    const std::string tree = (dir / "t.svat").string();
    ASSERT_EQ(runCli({"atlas", "build", (dir / "s/city/city.obj").string(), "--obj-local", "--out", tree,
                      "--atlas-size", "64"})
                  .exitCode,
              0);
    auto sources = parseManifest(dir / "s/scene.json");
    ASSERT_TRUE(sources.ok()) << sources.message();
    auto scene = loadScene(*sources, dir / "cache");
    ASSERT_TRUE(scene.ok()) << scene.message();

    // Two street views 3 m above the ground: A at the west block's south facades, B at the east block's north ones
    // (the blocks span x -70..76 m, y -52..50 m).
    auto camera = [&](double x, double y, double yaw) {
        Camera c;
        c.position = {x, y, scene->terrainHeight(x, y) + 3.0};
        c.yawDeg = yaw;
        c.pitchDeg = 8.0;
        c.fovYDeg = 60.0;
        return c;
    };
    const Camera a = camera(-40.0, -70.0, 0.0), b = camera(40.0, 70.0, 180.0);
    const int w = 240, h = 150;
    gl::RenderTarget target(w, h);

    for (const city::CityMode mode : {city::CityMode::Atlas, city::CityMode::Original}) {
        SCOPED_TRACE(city::cityModeName(mode));
        city::CitySettings cs;
        cs.mode = mode;
        cs.threaded = false;
        cs.occlusion = false;
        cs.capacityBytes = 1ull << 30;
        // What each view holds alone, and both together.
        city::CityFrameStats st;
        std::uint64_t bytesA = 0, bytesB = 0, both = 0;
        std::vector<std::uint8_t> ampleA;
        {
            auto ample = city::CityRendererGL::create(*scene, tree, cs);
            ASSERT_TRUE(ample.ok()) << ample.message();
            (*ample)->complete(a, w, h);
            ampleA = drawCity(**ample, a, target, st);
            bytesA = st.residentBytes;
            EXPECT_EQ(st.allocatedBytes, st.residentBytes);
            if (mode == city::CityMode::Atlas) {
                EXPECT_GT(st.originalLeaves, 0) << "the facades at A are drawn with their originals";
            }
            EXPECT_EQ(st.missingOriginals, 0);
            (*ample)->complete(b, w, h);
            drawCity(**ample, b, target, st);
            both = st.residentBytes;
            EXPECT_EQ(st.evictedBlocks, 0u);
        }
        {
            auto ample = city::CityRendererGL::create(*scene, tree, cs);
            ASSERT_TRUE(ample.ok()) << ample.message();
            (*ample)->complete(b, w, h);
            drawCity(**ample, b, target, st);
            bytesB = st.residentBytes;
        }
        const std::uint64_t facade = 128u * 128u * 4u * 4u / 3u;
        cs.capacityBytes = std::max(bytesA, bytesB) + facade / 2; // each view fits, not both
        std::printf("%s: A %llu B %llu both %llu bytes, capacity %llu\n", city::cityModeName(mode),
                    (unsigned long long)bytesA, (unsigned long long)bytesB, (unsigned long long)both,
                    (unsigned long long)cs.capacityBytes);
        ASSERT_GT(both, cs.capacityBytes + facade) << "the two views together must not fit";

        // The tight renderer: A, a walk to B and back (a frame's paging only, within the upload budget of three
        // bands), A again.
        cs.uploadBytesPerFrame = 3 * facade / 6;
        auto tight = city::CityRendererGL::create(*scene, tree, cs);
        ASSERT_TRUE(tight.ok()) << tight.message();
        (*tight)->complete(a, w, h);
        const auto firstA = drawCity(**tight, a, target, st);
        EXPECT_TRUE(firstA == ampleA) << "A with the tight capacity is A";
        std::size_t evicted = 0, partialFrames = 0;
        auto walk = [&](const Camera& from, const Camera& to) {
            for (int i = 1; i <= 12; ++i) {
                const double t = i / 12.0;
                Camera c = to;
                c.position = from.position + (to.position - from.position) * t;
                c.yawDeg = from.yawDeg + (to.yawDeg - from.yawDeg) * t;
                (*tight)->update(c, w, h);
                drawCity(**tight, c, target, st);
                evicted += st.evictedBlocks;
                EXPECT_LE(st.allocatedBytes, cs.capacityBytes) << "frame " << i;
                EXPECT_EQ(st.allocatedBytes, st.residentBytes) << "frame " << i;
                EXPECT_LE(st.uploadedBytes, cs.uploadBytesPerFrame) << "frame " << i;
                partialFrames += st.coarserThanWanted + st.missingOriginals > 0;
            }
        };
        walk(a, b);
        walk(b, a);
        (*tight)->complete(a, w, h);
        const auto againA = drawCity(**tight, a, target, st);
        EXPECT_GT(evicted, 6u) << "the walk evicted bands";
        EXPECT_GT(partialFrames, 0u) << "the budget spread the uploads over frames";
        EXPECT_LE(st.allocatedBytes, cs.capacityBytes);
        EXPECT_EQ(st.allocatedBytes, st.residentBytes);
        if (mode == city::CityMode::Atlas) {
            EXPECT_GT(st.originalLeaves, 0);
        }
        EXPECT_EQ(st.coarserThanWanted + st.missingOriginals, 0);
        EXPECT_TRUE(againA == firstA) << "A after its bands were evicted and uploaded again is A";
        if (againA != firstA || std::getenv("SEASONVIEW_KEEP_TEST_FILES")) {
            const std::string m = city::cityModeName(mode);
            (void)writeImageAtomic(outputDir() / ("paging_first_" + m + ".png"), firstA.data(), w, h, 4);
            (void)writeImageAtomic(outputDir() / ("paging_again_" + m + ".png"), againA.data(), w, h, 4);
        }
    }
    EXPECT_EQ(gl::drainErrors(), "");
}
