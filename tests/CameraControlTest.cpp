// The viewer's camera controllers (core/camera/CameraControl.h) without a window: ground picking, never below the terrain,
// fly speed scaled with the height, the orbit's pivot kept in the centre, map panning and zooming that keep the
// ground point under the cursor, and the easing.
#include "CameraControl.h"

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <cmath>

using namespace seasonview;

namespace {

const glm::ivec2 kViewport(800, 600);

double flat(double, double) { return 10.0; }
// Rolling hills up to 60 m with slopes up to about 0.6.
double hills(double x, double y) { return 30.0 + 30.0 * std::sin(x / 50.0) * std::cos(y / 70.0); }

Camera downAt(double x, double y, double z) {
    Camera c;
    c.position = {x, y, z};
    c.pitchDeg = -90.0;
    c.yawDeg = 0.0;
    c.fovYDeg = 60.0;
    return c;
}

NavInput step(double dt = 1.0 / 60.0) {
    NavInput in;
    in.dt = dt;
    in.cursor = {400.0, 300.0};
    return in;
}

// Runs updates with no input until the camera has caught up with its target.
void settle(CameraNavigator& nav, int frames = 300) {
    for (int i = 0; i < frames; ++i) nav.update(step(), kViewport);
}

} // namespace

TEST(CameraControlTest, PickGroundFindsTheSurfaceUnderAPixel) {
    const Camera c = downAt(5.0, -3.0, 110.0);
    const auto centre = pickGround(c, {400.0, 300.0}, kViewport, flat);
    ASSERT_TRUE(centre);
    EXPECT_NEAR(centre->x, 5.0, 1e-6);
    EXPECT_NEAR(centre->y, -3.0, 1e-6);
    EXPECT_DOUBLE_EQ(centre->z, 10.0);
    // The right edge of the window: 100 m below, tan(30°) × aspect × 100 m east (yaw 0 looking down: right = east).
    const auto edge = pickGround(c, {800.0, 300.0}, kViewport, flat);
    ASSERT_TRUE(edge);
    EXPECT_NEAR(edge->x - 5.0, 100.0 * std::tan(M_PI / 6.0) * 800.0 / 600.0, 0.02);
    EXPECT_NEAR(edge->y, -3.0, 0.02);
    // A slope: z = 0.5 x seen from the side, looking east and 30° down from (0, 0, 100).
    Camera side;
    side.position = {0.0, 0.0, 100.0};
    side.yawDeg = 90.0;
    side.pitchDeg = -30.0;
    const auto hit = pickGround(side, {400.0, 300.0}, kViewport, [](double x, double) { return 0.5 * x; });
    ASSERT_TRUE(hit);
    // 100 - t sin30 = 0.5 t cos30  =>  t = 100 / (sin30 + 0.5 cos30)
    const double t = 100.0 / (0.5 + 0.5 * std::cos(M_PI / 6.0));
    EXPECT_NEAR(hit->x, t * std::cos(M_PI / 6.0), 0.02);
    EXPECT_NEAR(hit->z, 0.5 * hit->x, 1e-9);
    // Looking up at the sky over flat ground: nothing.
    Camera sky = side;
    sky.pitchDeg = 20.0;
    EXPECT_FALSE(pickGround(sky, {400.0, 300.0}, kViewport, flat, 1e4));
}

TEST(CameraControlTest, NeverBelowTheTerrainInAnyMode) {
    NavSettings s;
    for (NavMode mode : {NavMode::Fly, NavMode::Map, NavMode::Orbit}) {
        Camera start;
        start.position = {0.0, 0.0, 80.0};
        start.yawDeg = 30.0;
        start.pitchDeg = -20.0;
        CameraNavigator nav(start, hills, s);
        nav.setMode(mode, kViewport);
        for (int i = 0; i < 1200; ++i) {
            NavInput in = step();
            in.forward = true; // fly into the hills, and down
            in.down = true;
            in.fast = true;
            in.wheel = i % 10 == 0 ? 2.0 : 0.0; // zoom in hard (map, orbit)
            in.drag = {3.0, 2.0};               // and keep turning / panning
            const Camera& c = nav.update(in, kViewport);
            ASSERT_GE(c.position.z, hills(c.position.x, c.position.y) + s.clearance - 1e-9)
                << navModeName(mode) << " frame " << i;
            ASSERT_GE(nav.target().position.z,
                      hills(nav.target().position.x, nav.target().position.y) + s.clearance - 1e-9);
        }
    }
    // A camera handed in under the ground comes out above it.
    CameraNavigator buried(downAt(0.0, 0.0, -50.0), hills, s);
    EXPECT_GE(buried.camera().position.z, hills(0.0, 0.0) + s.clearance - 1e-9);
}

TEST(CameraControlTest, FlySpeedScalesWithHeightAboveGround) {
    NavSettings s;
    s.smoothing = 0.0; // no easing: the distance covered is the speed's
    auto covered = [&](double height, bool fast) {
        Camera c;
        c.position = {0.0, 0.0, 10.0 + height};
        c.pitchDeg = 0.0;
        CameraNavigator nav(c, flat, s);
        NavInput in = step(0.01);
        in.forward = true;
        in.fast = fast;
        const double speed = nav.flySpeed();
        nav.update(in, kViewport);
        EXPECT_NEAR(glm::length(nav.camera().position - c.position), speed * 0.01 * (fast ? 4.0 : 1.0), 1e-9);
        return speed;
    };
    const double low = covered(100.0, false), high = covered(1000.0, false);
    EXPECT_NEAR(high / low, 10.0, 1e-9);
    EXPECT_NEAR(low, s.flySpeedPerHeight * 100.0, 1e-9);
    EXPECT_NEAR(covered(2.0, false), s.minFlySpeed, 1e-9); // a floor near the ground
    covered(100.0, true);
}

TEST(CameraControlTest, OrbitKeepsThePivotInTheCentre) {
    Camera start;
    start.position = {0.0, -200.0, 150.0};
    start.yawDeg = 0.0;
    start.pitchDeg = -35.0;
    CameraNavigator nav(start, hills);
    const glm::dvec3 pivot(20.0, 10.0, hills(20.0, 10.0));
    nav.setMode(NavMode::Orbit, kViewport, pivot);
    const double d0 = glm::length(nav.target().position - pivot);
    for (int i = 0; i < 240; ++i) {
        NavInput in = step();
        in.drag = {4.0, i < 120 ? 1.0 : -1.0}; // around, and up and down
        const Camera& c = nav.update(in, kViewport);
        // The eased camera too looks straight at the pivot, all the way.
        const glm::dvec3 toPivot = glm::normalize(pivot - c.position);
        ASSERT_GT(glm::dot(toPivot, c.forward()), 1.0 - 1e-9) << "frame " << i;
    }
    settle(nav);
    EXPECT_NEAR(glm::length(nav.camera().position - pivot), d0, 1e-3);
    EXPECT_GT(std::abs(nav.camera().yawDeg - start.yawDeg), 90.0); // 960 px at 0.15 degrees: turned 144
    // The ground point picked at the window's centre is the pivot (unless a hill stands in front of it).
    const auto centre = pickGround(nav.camera(), {400.0, 300.0}, kViewport, hills);
    ASSERT_TRUE(centre);
    EXPECT_LT(glm::length(*centre - pivot), 0.05);
    // The wheel: closer by zoomPerNotch per notch.
    NavInput in = step();
    in.wheel = 2.0;
    nav.update(in, kViewport);
    settle(nav);
    EXPECT_NEAR(glm::length(nav.camera().position - pivot), d0 * 0.85 * 0.85, 1e-3);
}

TEST(CameraControlTest, MapPanAndZoomKeepTheGroundPointUnderTheCursor) {
    CameraNavigator nav(downAt(0.0, 0.0, 210.0), flat);
    nav.setMode(NavMode::Map, kViewport);
    const glm::dvec2 from(300.0, 200.0);
    const auto before = pickGround(nav.camera(), from, kViewport, flat);
    ASSERT_TRUE(before);
    NavInput in = step();
    in.drag = {120.0, -45.0};
    nav.update(in, kViewport);
    settle(nav);
    const auto after = pickGround(nav.camera(), from + in.drag, kViewport, flat);
    ASSERT_TRUE(after);
    EXPECT_LT(glm::length(*after - *before), 0.05) << "the dragged point follows the cursor";
    EXPECT_DOUBLE_EQ(nav.camera().pitchDeg, -90.0);

    // Zoom in two notches at a corner of the window: the point there stays there, the height shrinks.
    const glm::dvec2 corner(700.0, 500.0);
    const auto under = pickGround(nav.camera(), corner, kViewport, flat);
    ASSERT_TRUE(under);
    const double h0 = nav.camera().position.z - 10.0;
    NavInput zoom = step();
    zoom.cursor = corner;
    zoom.wheel = 2.0;
    nav.update(zoom, kViewport);
    settle(nav);
    const auto still = pickGround(nav.camera(), corner, kViewport, flat);
    ASSERT_TRUE(still);
    EXPECT_LT(glm::length(*still - *under), 0.05);
    EXPECT_NEAR(nav.camera().position.z - 10.0, h0 * 0.85 * 0.85, 1e-3);
}

TEST(CameraControlTest, EasesTowardsTheTargetWithoutJumping) {
    NavSettings s;
    s.smoothing = 0.1;
    CameraNavigator nav(downAt(0.0, 0.0, 110.0), flat, s);
    nav.setMode(NavMode::Map, kViewport);
    NavInput in = step(0.01);
    in.drag = {200.0, 0.0};
    nav.update(in, kViewport);
    const double target = nav.target().position.x, moved = nav.camera().position.x;
    // After 10 ms of a 100 ms time constant: 1 - e^-0.1 of the way.
    EXPECT_NEAR(moved / target, 1.0 - std::exp(-0.1), 1e-9);
    settle(nav, 200);
    EXPECT_NEAR(nav.camera().position.x, target, 1e-6);
    // A bookmark jumps at once.
    const Camera mark = downAt(500.0, 400.0, 300.0);
    nav.jumpTo(mark);
    EXPECT_EQ(nav.camera().position, mark.position);
}
