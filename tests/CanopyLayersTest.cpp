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
