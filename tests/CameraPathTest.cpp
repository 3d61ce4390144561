#include "CameraPath.h"
#include "TestUtil.h"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include <fstream>

using namespace seasonview;
using namespace seasonview::test;

namespace {
PathScene scene() {
    PathScene s;
    s.localMin = {-1000, -1000};
    s.localMax = {1000, 1000};
    s.terrainHeight = [](double x, double) { return 100.0 + 0.01 * x; };
    return s;
}
} // namespace

TEST(CameraPathTest, NamedPathsStayOverTheSceneAndAboveTheTerrain) {
    const PathScene s = scene();
    for (const char* name : {"flyover", "orbit", "dive", "fast", "random"}) {
        auto p = CameraPath::named(name, s, 7);
        ASSERT_TRUE(p.ok()) << name;
        for (int i = 0; i <= 100; ++i) {
            const Camera c = p->at(i / 100.0, s.terrainHeight);
            EXPECT_LE(std::fabs(c.position.x), 1000.0) << name;
            EXPECT_LE(std::fabs(c.position.y), 1000.0) << name;
            EXPECT_GT(c.position.z, s.terrainHeight(c.position.x, c.position.y)) << name;
            EXPECT_GE(c.pitchDeg, -90.0);
            EXPECT_LE(c.pitchDeg, 90.0);
        }
    }
    EXPECT_FALSE(CameraPath::named("spiral", s).ok());
}

TEST(CameraPathTest, FlyoverIsStraightAt45Degrees) {
    const PathScene s = scene();
    auto p = CameraPath::named("flyover", s);
    ASSERT_TRUE(p.ok());
    const Camera a = p->at(0.0, s.terrainHeight), b = p->at(1.0, s.terrainHeight), m = p->at(0.5, s.terrainHeight);
    EXPECT_DOUBLE_EQ(a.pitchDeg, -45.0);
    EXPECT_NEAR(a.position.x, 0.0, 1e-9);
    EXPECT_NEAR(m.position.x, 0.0, 1e-9);
    EXPECT_LT(a.position.y, m.position.y);
    EXPECT_LT(m.position.y, b.position.y);
}

TEST(CameraPathTest, RandomIsSeeded) {
    const PathScene s = scene();
    const Camera a = CameraPath::named("random", s, 3)->at(0.37, s.terrainHeight);
    const Camera b = CameraPath::named("random", s, 3)->at(0.37, s.terrainHeight);
    const Camera c = CameraPath::named("random", s, 4)->at(0.37, s.terrainHeight);
    EXPECT_EQ(a.position, b.position);
    EXPECT_NE(a.position, c.position);
}

TEST(CameraPathTest, KeyframesInterpolateThroughTheKeys) {
    TempDir dir("camera-path");
    std::ofstream(dir / "p.json") << R"([{"time": 0, "x": 0, "y": 0, "z": 500, "yaw": 350, "pitch": -30},
        {"time": 1, "x": 100, "y": 0, "z": "+50", "yaw": 10, "pitch": -60, "fov": 40},
        {"time": 3, "x": 100, "y": 200, "z": 500, "yaw": 90, "pitch": -60}])";
    auto p = CameraPath::fromJson(dir / "p.json");
    ASSERT_TRUE(p.ok()) << p.message();
    const auto flat = [](double, double) { return 20.0; };
    const Camera k1 = p->at(1.0 / 3.0, flat);
    EXPECT_NEAR(k1.position.x, 100.0, 1e-9);
    EXPECT_NEAR(k1.position.z, 70.0, 1e-9); // +50 above terrain at 20 m
    EXPECT_NEAR(k1.yawDeg, 10.0, 1e-9);
    const Camera half = p->at(1.0 / 6.0, flat);
    EXPECT_TRUE(half.yawDeg > 350.0 || half.yawDeg < 10.0) << "shortest arc across north: " << half.yawDeg;
    struct Bad {
        const char* text;
        const char* needle;
    } bad[] = {{"[1]", "at least 2 keyframes"},
               {R"([{"time":0,"x":0,"y":0,"z":1,"yaw":0,"pitch":0},{"time":0,"x":0,"y":0,"z":1,"yaw":0,"pitch":0}])",
                "times must increase"},
               {R"([{"time":0,"x":0,"y":0,"yaw":0,"pitch":0},{"time":1,"x":0,"y":0,"z":1,"yaw":0,"pitch":0}])",
                "'z' is missing"},
               {R"([{"time":0,"x":"a","y":0,"z":1,"yaw":0,"pitch":0},{"time":1,"x":0,"y":0,"z":1,"yaw":0,"pitch":0}])",
                "'x' must be a number"},
               {"{", "malformed JSON"}};
    for (const Bad& b : bad) {
        std::ofstream(dir / "bad.json") << b.text;
        auto r = CameraPath::fromJson(dir / "bad.json");
        ASSERT_FALSE(r.ok()) << b.text;
        EXPECT_NE(r.message().find(b.needle), std::string::npos) << r.message();
    }
}
