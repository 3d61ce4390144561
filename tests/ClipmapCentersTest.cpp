#include "ClipmapCenters.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

using namespace seasonview;

namespace {
ViewSetup view(double pitch, double yaw = 0.0, double height = 150.0) {
    ViewSetup v;
    v.camera.position = {100, 200, height};
    v.camera.yawDeg = yaw;
    v.camera.pitchDeg = pitch;
    v.width = 1920;
    v.height = 1080;
    v.aspect = 1920.0 / 1080.0;
    return v;
}
ClipmapGeometry geometry() {
    ClipmapGeometry g;
    g.levels = 6;
    g.size = 1024;
    g.texelSize0 = 0.25;
    return g;
}
} // namespace

TEST(ClipmapCentersTest, NamesRoundTrip) {
    EXPECT_EQ(placementNames(), "concentric|offset|footprint");
    for (auto p : {CenterPlacement::Concentric, CenterPlacement::Offset, CenterPlacement::Footprint})
        EXPECT_EQ(parsePlacement(placementName(p)), p);
    EXPECT_FALSE(parsePlacement("spiral"));
}

TEST(ClipmapCentersTest, ConcentricIsBelowTheCamera) {
    for (const auto& c : placeCenters(CenterPlacement::Concentric, view(-30), geometry())) {
        EXPECT_DOUBLE_EQ(c.x, 100);
        EXPECT_DOUBLE_EQ(c.y, 200);
    }
}

TEST(ClipmapCentersTest, OffsetIsConcentricNearNadir) {
    // Pitch -80: 10 degrees from nadir, inside the 15 degree switch.
    const auto c = placeCenters(CenterPlacement::Offset, view(-80), geometry());
    for (const auto& p : c) {
        EXPECT_DOUBLE_EQ(p.x, 100);
        EXPECT_DOUBLE_EQ(p.y, 200);
    }
    // Pitch -70: 20 degrees from nadir: offset along the view's ground direction (north).
    const auto d = placeCenters(CenterPlacement::Offset, view(-70), geometry());
    EXPECT_GT(d[0].y, 200.0);
    EXPECT_NEAR(d[0].x, 100.0, 1e-9);
}

TEST(ClipmapCentersTest, OffsetFrontEdgesCoincideOnTheFrustumBottom) {
    const ViewSetup v = view(-30, 90); // looking east
    const ClipmapGeometry g = geometry();
    const auto c = placeCenters(CenterPlacement::Offset, v, g);
    const auto bottom = groundHit(v, 0.0, -1.0);
    ASSERT_TRUE(bottom);
    // Bottom ray: 60 degrees below the horizon from 150 m: 150 / tan(60) = 86.6 m ahead.
    EXPECT_NEAR(bottom->x - 100.0, 150.0 / std::tan(60.0 * 3.14159265358979 / 180.0), 1e-6);
    for (int l = 0; l < g.levels; ++l) {
        const double frontEdge = c[size_t(l)].x - 0.5 * g.extent(l);
        EXPECT_NEAR(frontEdge, bottom->x, 1e-6) << "level " << l;
        EXPECT_NEAR(c[size_t(l)].y, 200.0, 1e-9);
    }
}

TEST(ClipmapCentersTest, CameraLookingAboveTheHorizon) {
    // Pitch +40 with a 60 degree fov: no screen ray reaches the ground.
    const ViewSetup v = view(40, 0);
    EXPECT_FALSE(groundHit(v, 0.0, -1.0));
    const auto c = placeCenters(CenterPlacement::Offset, v, geometry());
    // Levels start at the camera's foot and extend forward (north).
    EXPECT_NEAR(c[0].y - 0.5 * geometry().extent(0), 200.0, 1e-9);
    const auto f = placeCenters(CenterPlacement::Footprint, v, geometry());
    EXPECT_EQ(f.size(), 6u);
    EXPECT_EQ(measureCoverage(v, geometry(), f).groundSamples, 0);
}

TEST(ClipmapCentersTest, NeededLevelFromFootprint) {
    const ClipmapGeometry g = geometry();
    EXPECT_EQ(neededLevel(0.1, g), 0);
    EXPECT_EQ(neededLevel(0.25, g), 0);
    EXPECT_EQ(neededLevel(0.49, g), 0);
    EXPECT_EQ(neededLevel(0.5, g), 1);
    EXPECT_EQ(neededLevel(7.9, g), 4);
    EXPECT_EQ(neededLevel(1e6, g), 6); // beyond the clip levels: the resident pyramid is enough
}

TEST(ClipmapCentersTest, StraightDownEverythingIsCovered) {
    // Straight down, a level needed by a pixel spans at most N pixels: levels of N >= the viewport's width cover
    // every pixel (with 1024² levels on a 1920-wide view, 17 % of the pixels would get a level too coarse).
    const ViewSetup v = view(-90, 0, 150);
    ClipmapGeometry g = geometry();
    g.size = 2048;
    for (auto p : {CenterPlacement::Concentric, CenterPlacement::Offset, CenterPlacement::Footprint}) {
        const CoverageStats s = measureCoverage(v, g, placeCenters(p, v, g));
        EXPECT_GT(s.groundSamples, 1000);
        EXPECT_DOUBLE_EQ(s.coverage, 1.0) << placementName(p);
    }
}

// The configuration: 1920x1080, 150 m above ground, pitch -30, 6 levels of 1024².
TEST(ClipmapCentersTest, CoverageOffsetBeatsConcentricAndFootprintBeatsOffset) {
    const ViewSetup v = view(-30, 35);
    const ClipmapGeometry g = geometry();
    double cov[3];
    int i = 0;
    for (auto p : {CenterPlacement::Concentric, CenterPlacement::Offset, CenterPlacement::Footprint}) {
        const CoverageStats s = measureCoverage(v, g, placeCenters(p, v, g), 2);
        cov[i++] = s.coverage;
        std::printf("%-10s coverage %.4f  mean level deficit %.4f\n", placementName(p), s.coverage, s.meanLevelDeficit);
    }
    EXPECT_GE(cov[1] - cov[0], 0.15) << "offset at least 15 points above concentric";
    EXPECT_GT(cov[2], cov[1]) << "footprint above offset";
}

TEST(ClipmapCentersTest, FootprintLevelsAreNested) {
    const ClipmapGeometry g = geometry();
    for (double pitch : {-10.0, -30.0, -50.0, -70.0})
        for (double height : {20.0, 150.0, 800.0}) {
            const ViewSetup v = view(pitch, 20, height);
            const auto c = placeCenters(CenterPlacement::Footprint, v, g);
            for (int l = 1; l < g.levels; ++l) {
                const double slack = 0.5 * (g.extent(l) - g.extent(l - 1)) + 1e-6;
                EXPECT_LE(std::fabs(c[size_t(l)].x - c[size_t(l - 1)].x), slack);
                EXPECT_LE(std::fabs(c[size_t(l)].y - c[size_t(l - 1)].y), slack);
            }
            const double f = measureCoverage(v, g, c).coverage;
            const double o = measureCoverage(v, g, placeCenters(CenterPlacement::Offset, v, g)).coverage;
            EXPECT_GE(f, o - 0.005) << "pitch " << pitch << " height " << height;
        }
}
