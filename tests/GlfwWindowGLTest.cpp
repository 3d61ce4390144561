#include "RenderJob.h"
#include "TestUtil.h"

#include <gtest/gtest.h>

#include <cstdlib>

using namespace seasonview;
using namespace seasonview::test;

// Runs under xvfb-run from CTest (see tests/CMakeLists.txt); skipped where there is no display.
TEST(GlfwWindowGLTest, SameImageAsHeadless) {
    if (!std::getenv("DISPLAY")) {
        // Under xvfb-run (CTest sets this) a missing display is a failure, not a skip.
        ASSERT_EQ(std::getenv("SEASONVIEW_REQUIRE_DISPLAY"), nullptr) << "xvfb-run gave no DISPLAY";
        GTEST_SKIP() << "no DISPLAY: the windowed path runs in the Xvfb test";
    }
    TempDir dir("glfw");
    auto scene = writeTestPair(dir.path(), 96, 64, 0.5);
    ASSERT_TRUE(scene.ok()) << scene.message();
    Camera cam;
    cam.position = {0, -40, 25};
    cam.pitchDeg = -40;
    app::RenderSettings settings;
    settings.cacheDir = dir / "cache";
    settings.windowed = true;
    auto win = app::renderStills(*scene, 160, 120, {{cam, {}, dir / "window.png", {}, {}, {}}}, settings);
    ASSERT_TRUE(win.ok()) << win.message();
    EXPECT_EQ(win->platform, "GLFW window");
    settings.windowed = false;
    auto egl = app::renderStills(*scene, 160, 120, {{cam, {}, dir / "egl.png", {}, {}, {}}}, settings);
    ASSERT_TRUE(egl.ok()) << egl.message();
    auto a = readImageU8(dir / "window.png", 3);
    auto b = readImageU8(dir / "egl.png", 3);
    ASSERT_TRUE(a.ok() && b.ok());
    const ImageDiff d = compareRgb(a->pixels, b->pixels, 160, 120, 3);
    EXPECT_EQ(d.maxDelta, 0) << "one renderer code path for both contexts";
}
