// Occlusion culling of the atlas tree's nodes (city/CityRendererGL.h), frame by frame in one process: along a walk
// down a street of a block city, a turn at a crossing and a rise over the roofs, every frame's picture is the one
// drawn without occlusion culling while hidden nodes are skipped. After the first frame this runs the temporal path:
// answers kept between frames, nodes found hidden tested again, nodes new in view drawn untested, visible answers
// trusted for a few frames.
#include "CityJob.h"
#include "CityRendererGL.h"
#include "ClipmapGL.h"
#include "ClipmapTerrainRendererGL.h"
#include "RenderJob.h"
#include "TestUtil.h"
#include "gl/GlDebug.h"

#include <gtest/gtest.h>

#include <cstdio>

using namespace seasonview;
using namespace seasonview::test;

TEST(CityOcclusionGLTest, EveryFrameOfAWalkMatchesTheUnculledPicture) {
    ASSERT_TRUE(headlessContext());
    TempDir dir("city-occlusion");
    const CliResult s = runCli({"synth", "--out", (dir / "s").string(), "--size-m", "512", "--gsd", "1", "--block-city",
                                "160", "--facade-size", "64"});
    ASSERT_EQ(s.exitCode, 0) << s.err;
    auto sources = parseManifest(dir / "s/scene.json");
    ASSERT_TRUE(sources.ok()) << sources.message();
    auto scene = loadScene(*sources, dir / "cache");
    ASSERT_TRUE(scene.ok()) << scene.message();

    // The terrain, drawn first (its depth hides buildings too).
    auto pyramids = app::preparePyramids(*scene, dir / "cache");
    ASSERT_TRUE(pyramids.ok()) << pyramids.message();
    auto elevation = app::prepareElevation(*scene, dir / "cache");
    ASSERT_TRUE(elevation.ok()) << elevation.message();
    ClipmapOptions co;
    co.size = 256;
    auto clip = ClipmapGL::create(*pyramids, co);
    ASSERT_TRUE(clip.ok()) << clip.message();
    auto terrain = ClipmapTerrainRendererGL::create(*scene, **clip, *elevation ? &**elevation : nullptr, {});
    ASSERT_TRUE(terrain.ok()) << terrain.message();
    const ClipmapGeometry geometry = app::clipmapGeometry(*scene, (*clip)->schedule().layout());

    auto tree = app::prepareCityTree(*scene, dir / "cache", "");
    ASSERT_TRUE(tree.ok()) << tree.message();
    city::CitySettings cs;
    cs.capacityBytes = 1ull << 30; // everything the views want resident after complete(): the same levels both ways
    cs.threaded = false;
    auto culled = city::CityRendererGL::create(*scene, tree->string(), cs);
    ASSERT_TRUE(culled.ok()) << culled.message();
    cs.occlusion = false;
    auto plain = city::CityRendererGL::create(*scene, tree->string(), cs);
    ASSERT_TRUE(plain.ok()) << plain.message();

    const int w = 320, h = 200;
    gl::RenderTarget a(w, h), b(w, h);
    auto frame = [&](const Camera& cam, city::CityRendererGL& city, const gl::RenderTarget& target) {
        (*clip)->update(app::clipmapCentres(*scene, cam, w, h, CenterPlacement::Footprint, geometry));
        (*clip)->completeSynchronously();
        (*terrain)->updateGeometry(cam, h);
        (*terrain)->completeGeometry();
        (*terrain)->render(cam, {}, target);
        city.complete(cam, w, h);
        return city.draw(cam, terrain->get(), target);
    };

    // 12 frames walking north up a street (x = 2.5 m), 8 turning east at the crossing (y = -59 m), 8 rising over the
    // roofs.
    std::vector<Camera> path;
    auto at = [&](double x, double y, double above, double yaw, double pitch) {
        Camera c;
        c.position = {x, y, scene->terrainHeight(x, y) + above};
        c.yawDeg = yaw;
        c.pitchDeg = pitch;
        c.fovYDeg = 60.0;
        path.push_back(c);
    };
    for (int i = 0; i < 12; ++i) at(2.5, -110.0 + 4.6 * i, 2.0, 3.0 - 0.5 * i, 2.0);
    for (int i = 1; i <= 8; ++i) at(2.5, -59.4, 2.0, -2.5 + 11.5 * i, 2.0);
    for (int i = 1; i <= 8; ++i) at(2.5 + 4.0 * i, -59.4, 2.0 + 8.0 * i, 89.5, 2.0 - 3.0 * i);

    int occludedLater = 0, fewer = 0, waitsLater = 0;
    for (std::size_t f = 0; f < path.size(); ++f) {
        const city::CityFrameStats on = frame(path[f], **culled, a);
        const city::CityFrameStats off = frame(path[f], **plain, b);
        std::printf("frame %2zu: %2d atlases + %d leaves (%2d + %d without), %2d hidden, %2d queries, %d waits\n", f,
                    on.atlasNodes, on.originalLeaves, off.atlasNodes, off.originalLeaves, on.occludedNodes,
                    on.occlusionQueries, on.occlusionWaits);
        EXPECT_TRUE(a.readRgba() == b.readRgba()) << "frame " << f << ": occlusion culling changed the picture";
        EXPECT_EQ(off.occludedNodes + off.occlusionQueries, 0);
        EXPECT_LE(on.atlasNodes + on.originalLeaves, off.atlasNodes + off.originalLeaves) << "frame " << f;
        EXPECT_EQ(on.coarserThanWanted, 0) << "frame " << f;
        if (f > 0) {
            occludedLater += on.occludedNodes;
            waitsLater += on.occlusionWaits;
        }
        fewer += on.atlasNodes + on.originalLeaves < off.atlasNodes + off.originalLeaves;
    }
    EXPECT_GT(occludedLater, 0) << "hidden nodes are skipped after the first frame too";
    EXPECT_GE(fewer, 8) << "the street frames draw fewer nodes";
    EXPECT_LE(waitsLater, 2 * int(path.size())) << "a frame that knows the last one's answers waits once or twice";
    EXPECT_EQ(gl::drainErrors(), "");
}
