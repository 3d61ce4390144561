#include "CameraPath.h"
#include "TestUtil.h"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include <array>
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

// The named paths are in scene-relative units: on an off-centre, non-square scene they stay over it, scale with it
// and centre on it.
TEST(CameraPathTest, NamedPathsScaleWithTheScene) {
    PathScene s;
    s.localMin = {5000, -200};
    s.localMax = {9000, 1800}; // 4 km × 2 km, centred at (7000, 800)
    s.terrainHeight = [](double, double y) { return 300.0 + 0.05 * y; };
    for (const char* name : {"flyover", "orbit", "dive", "fast", "random"}) {
        auto p = CameraPath::named(name, s, 3);
        ASSERT_TRUE(p.ok()) << name;
        glm::dvec2 lo(1e30), hi(-1e30), sum(0.0);
        for (int i = 0; i <= 200; ++i) {
            const Camera c = p->at(i / 200.0, s.terrainHeight);
            EXPECT_GE(c.position.x, 5000.0) << name << " " << i;
            EXPECT_LE(c.position.x, 9000.0) << name << " " << i;
            EXPECT_GE(c.position.y, -200.0) << name << " " << i;
            EXPECT_LE(c.position.y, 1800.0) << name << " " << i;
            EXPECT_GT(c.position.z, s.terrainHeight(c.position.x, c.position.y)) << name << " " << i;
            lo = glm::min(lo, glm::dvec2(c.position));
            hi = glm::max(hi, glm::dvec2(c.position));
            sum += glm::dvec2(c.position);
        }
        // Each path travels a good part of the scene's smaller half-size (1 km), not metres of it.
        EXPECT_GT(std::max(hi.x - lo.x, hi.y - lo.y), 500.0) << name;
        if (std::string(name) == "orbit") {
            EXPECT_NEAR(sum.x / 201.0, 7000.0, 50.0);
            EXPECT_NEAR(sum.y / 201.0, 800.0, 50.0);
        }
    }
}

// dive: from straight down, high up, to a near-horizontal view low over the ground.
TEST(CameraPathTest, DiveGoesFromTopDownToNearHorizontal) {
    const PathScene s = scene();
    auto p = CameraPath::named("dive", s);
    ASSERT_TRUE(p.ok());
    const Camera a = p->at(0.0, s.terrainHeight), b = p->at(1.0, s.terrainHeight);
    EXPECT_NEAR(a.pitchDeg, -90.0, 1e-9);
    EXPECT_GT(b.pitchDeg, -10.0);
    EXPECT_GT(a.position.z - s.terrainHeight(a.position.x, a.position.y),
              20.0 * (b.position.z - s.terrainHeight(b.position.x, b.position.y)));
    double last = -91.0;
    for (int i = 0; i <= 100; ++i) { // the view only rises
        const double pitch = p->at(i / 100.0, s.terrainHeight).pitchDeg;
        EXPECT_GE(pitch, last - 1e-9) << i;
        last = pitch;
    }
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

// Between unevenly timed keys the camera's velocity and turn rates do not jump at the keys (C1 in time), heights
// and angles stay within the keys around them (a camera held 2 m above the ground does not dip into it), and a
// held heading does not wobble.
TEST(CameraPathTest, KeyframePathsAreSmoothAtTheKeys) {
    TempDir dir("camera-path-smooth");
    std::ofstream(dir / "p.json") << R"([{"time": 0, "x": 0, "y": 0, "z": "+2", "yaw": 0, "pitch": -10},
        {"time": 1, "x": 100, "y": 0, "z": "+2", "yaw": 90, "pitch": -40, "fov": 50},
        {"time": 10, "x": 200, "y": 300, "z": "+50", "yaw": 90, "pitch": -20},
        {"time": 11, "x": 180, "y": 400, "z": 400, "yaw": 200, "pitch": -80}])";
    auto p = CameraPath::fromJson(dir / "p.json");
    ASSERT_TRUE(p.ok()) << p.message();
    const auto ground = [](double x, double y) { return 20.0 + 0.05 * x + 0.02 * y; };
    const double T = 11.0, e = 1e-7;
    auto rates = [&](double u0, double u1) {
        const Camera a = p->at(u0, ground), b = p->at(u1, ground);
        double dyaw = b.yawDeg - a.yawDeg;
        if (dyaw > 180) dyaw -= 360;
        if (dyaw < -180) dyaw += 360;
        const double dt = (u1 - u0) * T;
        return std::array<double, 5>{(b.position.x - a.position.x) / dt, (b.position.y - a.position.y) / dt,
                                     (b.position.z - a.position.z) / dt, dyaw / dt, (b.pitchDeg - a.pitchDeg) / dt};
    };
    for (const double tk : {1.0, 10.0}) {
        const double u = tk / T;
        const auto left = rates(u - e, u), right = rates(u, u + e);
        for (std::size_t c = 0; c < 5; ++c)
            EXPECT_NEAR(left[c], right[c], 1e-3 * std::max(1.0, std::fabs(left[c]))) << "key at t=" << tk << " channel " << c;
    }
    // Monotone heights and angles: +2 m held over the first segment, the heading held at 90° over the long one.
    for (int i = 0; i <= 1000; ++i) {
        const double u = i / 1000.0;
        const Camera c = p->at(u, ground);
        const double above = c.position.z - ground(c.position.x, c.position.y);
        if (u * T <= 1.0) {
            EXPECT_NEAR(above, 2.0, 1e-9) << u;
        }
        if (u * T >= 1.0 && u * T <= 10.0) {
            EXPECT_NEAR(c.yawDeg, 90.0, 1e-9) << u;
            EXPECT_GE(above, 2.0 - 1e-9) << u;
            EXPECT_LE(above, 50.0 + 1e-9) << u;
        }
        EXPECT_GE(c.pitchDeg, -80.0 - 1e-9);
        EXPECT_LE(c.pitchDeg, -10.0 + 1e-9);
        EXPECT_GE(c.fovYDeg, 50.0 - 1e-9);
        EXPECT_LE(c.fovYDeg, 60.0 + 1e-9);
    }
}

// `fast`: high speed with sudden turns: the heading is held along each leg and snaps round at its end.
TEST(CameraPathTest, FastTurnsSuddenly) {
    const PathScene s = scene();
    auto p = CameraPath::named("fast", s);
    ASSERT_TRUE(p.ok());
    const int frames = 300;
    double maxStep = 0.0, minSpeed = 1e9, maxSpeed = 0.0;
    Camera prev = p->at(0.0, s.terrainHeight);
    EXPECT_NEAR(prev.yawDeg, 90.0, 1e-9) << "first leg: east";
    for (int i = 1; i < frames; ++i) {
        const Camera c = p->at(i / double(frames - 1), s.terrainHeight);
        double d = std::fabs(c.yawDeg - prev.yawDeg);
        maxStep = std::max(maxStep, std::min(d, 360.0 - d));
        const double v = glm::length(glm::dvec2(c.position) - glm::dvec2(prev.position));
        minSpeed = std::min(minSpeed, v);
        maxSpeed = std::max(maxSpeed, v);
        prev = c;
    }
    EXPECT_GE(maxStep, 20.0) << "a 90° turn within a few frames";
    // 7.9 half-widths of 1000 m in all: never slower than 60 % of the mean speed, through the turns too.
    EXPECT_GT(minSpeed, 0.6 * 7900.0 / (frames - 1)) << maxSpeed;
    // Mid-leg the heading is the leg's own (legs: east, north, west, north, east, north, west).
    EXPECT_NEAR(p->at(0.1, s.terrainHeight).yawDeg, 90.0, 1e-9);
}

// `orbit` circles the centre looking at it all the way round (yaw 0 = north, 90 = east).
TEST(CameraPathTest, OrbitLooksAtTheCentre) {
    const PathScene s = scene();
    auto p = CameraPath::named("orbit", s);
    ASSERT_TRUE(p.ok());
    for (int i = 0; i <= 100; ++i) {
        const Camera c = p->at(i / 100.0, s.terrainHeight);
        const glm::dvec2 toCentre = glm::normalize(-glm::dvec2(c.position));
        const double yaw = c.yawDeg * 3.14159265358979323846 / 180.0;
        const glm::dvec2 forward(std::sin(yaw), std::cos(yaw));
        EXPECT_GT(glm::dot(toCentre, forward), std::cos(3.0 * 3.14159265358979323846 / 180.0)) << i << " yaw " << c.yawDeg;
    }
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
    // Every key is met exactly, in every channel, whatever kind of height its neighbours have (on a slope).
    const auto slope = [](double x, double y) { return 20.0 + 0.3 * x - 0.1 * y; };
    const struct {
        double u, x, y, z, yaw, pitch, fov;
    } keys[] = {{0.0, 0, 0, 500, 350, -30, 60},
                {1.0 / 3.0, 100, 0, 50 + slope(100, 0), 10, -60, 40},
                {1.0, 100, 200, 500, 90, -60, 60}};
    for (const auto& k : keys) {
        const Camera c = p->at(k.u, slope);
        EXPECT_NEAR(c.position.x, k.x, 1e-9) << k.u;
        EXPECT_NEAR(c.position.y, k.y, 1e-9) << k.u;
        EXPECT_NEAR(c.position.z, k.z, 1e-9) << k.u;
        EXPECT_NEAR(c.yawDeg, k.yaw, 1e-9) << k.u;
        EXPECT_NEAR(c.pitchDeg, k.pitch, 1e-9) << k.u;
        EXPECT_NEAR(c.fovYDeg, k.fov, 1e-9) << k.u;
    }
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
