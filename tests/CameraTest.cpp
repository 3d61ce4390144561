#include "Camera.h"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>
#include <glm/vec4.hpp>

using namespace seasonview;

namespace {
void expectVec(glm::dvec3 a, glm::dvec3 b) {
    EXPECT_NEAR(a.x, b.x, 1e-12);
    EXPECT_NEAR(a.y, b.y, 1e-12);
    EXPECT_NEAR(a.z, b.z, 1e-12);
}
} // namespace

TEST(CameraTest, YawIsCompassHeadingClockwiseFromNorth) {
    Camera c;
    c.pitchDeg = 0;
    c.yawDeg = 0;
    expectVec(c.forward(), {0, 1, 0});
    expectVec(c.right(), {1, 0, 0});
    c.yawDeg = 90;
    expectVec(c.forward(), {1, 0, 0});
    expectVec(c.right(), {0, -1, 0});
    c.yawDeg = 180;
    expectVec(c.forward(), {0, -1, 0});
}

TEST(CameraTest, StraightDownAndHorizonHaveOrthonormalBasis) {
    for (double pitch : {-90.0, -45.0, 0.0, 30.0, 90.0}) {
        Camera c;
        c.yawDeg = 37;
        c.pitchDeg = pitch;
        const glm::dvec3 f = c.forward(), r = c.right(), u = c.up();
        EXPECT_NEAR(glm::length(f), 1, 1e-12);
        EXPECT_NEAR(glm::length(u), 1, 1e-12);
        EXPECT_NEAR(glm::dot(f, r), 0, 1e-12);
        EXPECT_NEAR(glm::dot(f, u), 0, 1e-12);
        EXPECT_GE(u.z, -1e-12) << "image up never points below the horizon";
    }
    Camera down;
    down.pitchDeg = -90;
    expectVec(down.forward(), {0, 0, -1});
    expectVec(down.up(), {0, 1, 0}); // heading 0 straight down: north is up in the image
}

TEST(CameraTest, ViewMatrixLooksDownMinusZ) {
    Camera c;
    c.position = {100, 200, 50};
    c.yawDeg = 120;
    c.pitchDeg = -30;
    const glm::dmat4 v = c.viewMatrix();
    const glm::dvec4 eye = v * glm::dvec4(c.position, 1.0);
    expectVec(glm::dvec3(eye), {0, 0, 0});
    const glm::dvec4 ahead = v * glm::dvec4(c.position + 10.0 * c.forward(), 1.0);
    expectVec(glm::dvec3(ahead), {0, 0, -10});
    const glm::dvec4 right = v * glm::dvec4(c.position + 3.0 * c.right(), 1.0);
    expectVec(glm::dvec3(right), {3, 0, 0});
}

TEST(CameraTest, ReversedZProjection) {
    Camera c;
    const glm::dmat4 p = c.projectionMatrix(16.0 / 9.0, 0.5);
    auto depth = [&](double dist) {
        const glm::dvec4 clip = p * glm::dvec4(0, 0, -dist, 1);
        return clip.z / clip.w;
    };
    EXPECT_NEAR(depth(0.5), 1.0, 1e-12);
    EXPECT_NEAR(depth(1.0), 0.5, 1e-12);
    EXPECT_GT(depth(1e6), 0.0);
    EXPECT_LT(depth(1e6), 1e-6);
    // Top of the frustum at 60 degrees vertical fov.
    const glm::dvec4 top = p * glm::dvec4(0, std::tan(3.14159265358979 / 6), -1, 1);
    EXPECT_NEAR(top.y / top.w, 1.0, 1e-9);
}

TEST(CameraTest, ParsesFiveAndSixFields) {
    auto a = parseCamera("10,-20.5,300,45,-60");
    ASSERT_TRUE(a.ok()) << a.message();
    EXPECT_DOUBLE_EQ(a->camera.position.x, 10);
    EXPECT_DOUBLE_EQ(a->camera.position.y, -20.5);
    EXPECT_DOUBLE_EQ(a->camera.position.z, 300);
    EXPECT_DOUBLE_EQ(a->camera.yawDeg, 45);
    EXPECT_DOUBLE_EQ(a->camera.pitchDeg, -60);
    EXPECT_DOUBLE_EQ(a->camera.fovYDeg, 60);
    EXPECT_FALSE(a->heightAboveTerrain);
    auto b = parseCamera("1, 2, 3, 4, -5, 35");
    ASSERT_TRUE(b.ok()) << b.message();
    EXPECT_DOUBLE_EQ(b->camera.fovYDeg, 35);
}

TEST(CameraTest, PlusHIsAboveTerrain) {
    auto a = parseCamera("5,6,+120,0,-90");
    ASSERT_TRUE(a.ok()) << a.message();
    ASSERT_TRUE(a->heightAboveTerrain);
    EXPECT_DOUBLE_EQ(*a->heightAboveTerrain, 120);
    const Camera c = a->resolve([](double x, double y) { return 1000 + x + y; });
    EXPECT_DOUBLE_EQ(c.position.z, 1131);
}

TEST(CameraTest, RoundTripsThroughString) {
    Camera c;
    c.position = {1.25, -3.5, 1234.5678};
    c.yawDeg = 271.5;
    c.pitchDeg = -12.25;
    c.fovYDeg = 42;
    auto p = parseCamera(c.toString());
    ASSERT_TRUE(p.ok()) << p.message();
    EXPECT_DOUBLE_EQ(p->camera.position.z, c.position.z);
    EXPECT_DOUBLE_EQ(p->camera.yawDeg, c.yawDeg);
    EXPECT_DOUBLE_EQ(p->camera.fovYDeg, c.fovYDeg);
}

TEST(CameraTest, RejectsBadStrings) {
    struct Case {
        const char* text;
        const char* needle;
    } cases[] = {
        {"", "fields"},
        {"1,2,3,4", "got 4 fields"},
        {"1,2,3,4,5,6,7", "got 7 fields"},
        {"1,2,abc,4,5", "Z 'abc' is not a number"},
        {"1,2,3,4,5x", "PITCH"},
        {"1,2,3,4,-91", "PITCH must be within"},
        {"1,2,3,4,5,0", "FOV must be within"},
        {"1,2,3,4,5,180", "FOV must be within"},
        {"1,2,+,4,5", "Z '+' is not a number"},
        {"nan,2,3,4,5", "X"},
        {"1,,3,4,5", "Y '' is not a number"},
    };
    for (const Case& c : cases) {
        auto r = parseCamera(c.text);
        ASSERT_FALSE(r.ok()) << c.text;
        EXPECT_NE(r.message().find(c.needle), std::string::npos) << c.text << " -> " << r.message();
        EXPECT_EQ(r.message().find('\n'), std::string::npos);
        EXPECT_EQ(r.message().rfind("camera '", 0), 0u) << r.message();
    }
}
