// How many stacked canopy layers a piece gets (foliage/CanopyRendererGL.h): all of them where the stack is tall on
// screen, fewer as it shrinks with distance, none below minLiftPixels.
#include "CanopyRendererGL.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace seasonview;

namespace {
int layersAt(double distance, double eyeHeight, const CanopyDrawSettings& s, int layers = 15) {
    const double ppr = 360.0 / (2.0 * std::tan(M_PI / 6.0)); // 360 rows, 60 degrees
    // A 10 m piece at `distance` east of the eye, terrain at 0 m.
    return canopyPieceLayers({0.0, 0.0, eyeHeight}, ppr, {distance, -5.0, 0.0}, {distance + 10.0, 5.0, 0.0}, s, layers);
}
} // namespace

TEST(CanopyLayersTest, LayersFollowTheStackOnScreen) {
    CanopyDrawSettings s;
    s.treeHeight = 15.0;
    // Level with the crowns and near: a stack of hundreds of pixels, every layer above the ground one.
    EXPECT_EQ(layersAt(20.0, 10.0, s), 15);
    // Thinning with distance: never more layers farther away, and about one per pixel of stack.
    int previous = 15;
    for (double d = 20.0; d < 20000.0; d *= 1.5) {
        const int n = layersAt(d, 10.0, s);
        EXPECT_LE(n, previous) << d;
        previous = n;
    }
    const double ppr = 360.0 / (2.0 * std::tan(M_PI / 6.0));
    const double d = 1000.0, stack = 15.0 * ppr * d / (d * d); // eye at the crowns' height: dz = 0
    EXPECT_EQ(layersAt(d, 15.0, s), int(std::ceil(stack)));
    // Under a pixel of stack: nothing.
    EXPECT_EQ(layersAt(15.0 * ppr * 2.0, 15.0, s), 0);
    // Straight down from high above, the stack is seen end-on: few layers.
    EXPECT_LE(canopyPieceLayers({0.0, 0.0, 3000.0}, ppr, {-5.0, -5.0, 0.0}, {5.0, 5.0, 0.0}, s, 15), 2);
    // Two pixels per layer halves them; no layer to draw (only the ground's): nothing; never more than asked for.
    s.pixelsPerLayer = 2.0;
    EXPECT_EQ(layersAt(d, 15.0, s), int(std::ceil(stack / 2.0)));
    EXPECT_EQ(layersAt(20.0, 10.0, s, 0), 0);
    EXPECT_EQ(layersAt(20.0, 10.0, s, 4), 4);
}

// Which patches the marched layers take: those every ray comes down through faster than the terrain under them
// rises; the rest are rasterised layer by layer.
TEST(CanopyLayersTest, PatchesMarchOnlyWhereRaysComeDownThroughTheStack) {
    const double h = 15.0;
    // Flat ground seen from above, down to about 6° over the horizon: marched.
    EXPECT_TRUE(canopyPatchMarches({0.0, 0.0, 200.0}, {-5.0, -5.0, 0.0}, {5.0, 5.0, 0.0}, h));
    EXPECT_TRUE(canopyPatchMarches({0.0, 0.0, 200.0}, {500.0, 0.0, 0.0}, {510.0, 10.0, 0.0}, h));
    // Nearly level with the crowns, below them, or level with them: rasterised.
    EXPECT_FALSE(canopyPatchMarches({0.0, 0.0, 30.0}, {500.0, 0.0, 0.0}, {510.0, 10.0, 0.0}, h));
    EXPECT_FALSE(canopyPatchMarches({0.0, 0.0, 10.0}, {20.0, 0.0, 0.0}, {30.0, 10.0, 0.0}, h));
    EXPECT_FALSE(canopyPatchMarches({0.0, 0.0, 15.0}, {-5.0, -5.0, 0.0}, {5.0, 5.0, 0.0}, h));
    // The same view down at 45° marches over gentle ground and not over a slope as steep as the rays.
    EXPECT_TRUE(canopyPatchMarches({0.0, 0.0, 215.0}, {190.0, 0.0, 0.0}, {200.0, 10.0, 1.0}, h));
    EXPECT_FALSE(canopyPatchMarches({0.0, 0.0, 215.0}, {190.0, 0.0, -10.0}, {200.0, 10.0, 0.0}, h));
}
