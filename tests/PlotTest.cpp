// The benchmark plot (app/Plot.h): a series measured only at some samples (coverage every 100th frame) is drawn,
// its measured samples joined across the unmeasured ones and dotted; a dense series is a line.
#include "Plot.h"
#include "Raster.h"
#include "TestUtil.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace seasonview;
using namespace seasonview::test;

namespace {

/// Pixels of colour (r, g, b) left of the legend (x < width - 300: the plot area).
std::size_t pixelsOf(const Image<std::uint8_t>& img, int r, int g, int b) {
    std::size_t n = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width - 300; ++x)
            n += img.at(x, y, 0) == r && img.at(x, y, 1) == g && img.at(x, y, 2) == b;
    return n;
}

} // namespace

TEST(PlotTest, SparseSamplesAreJoinedAndDotted) {
    TempDir dir("plot");
    const double nan = std::nan("");
    std::vector<double> sparse(1000, nan), dense(1000);
    for (int i = 0; i < 1000; i += 100) sparse[std::size_t(i)] = 0.5 + 0.04 * (i / 100);
    for (int i = 0; i < 1000; ++i) dense[std::size_t(i)] = 10.0 + std::sin(i * 0.05);
    std::vector<app::PlotPanel> panels(2);
    panels[0].title = "frame time (ms)";
    panels[0].series = {{"a", dense}};
    panels[1].title = "coverage";
    panels[1].yMin = 0.0;
    panels[1].yMax = 1.0;
    panels[1].series = {{"a", sparse}};
    ASSERT_TRUE(app::writeLinePlot(dir / "p.png", panels, "frame").ok());
    auto img = readImageU8(dir / "p.png", 3);
    ASSERT_TRUE(img.ok()) << img.message();
    // The series colour (the first: 214,39,40) in each panel's half of the picture.
    Image<std::uint8_t> topHalf = *img, bottomHalf = *img;
    for (int y = 0; y < img->height; ++y)
        for (int x = 0; x < img->width; ++x)
            for (int c = 0; c < 3; ++c) (y < img->height / 2 ? bottomHalf : topHalf).at(x, y, c) = 255;
    EXPECT_GT(pixelsOf(topHalf, 214, 39, 40), 1000u) << "the dense series is a line across the panel";
    EXPECT_GT(pixelsOf(bottomHalf, 214, 39, 40), 1000u) << "the sparse series is drawn: ten samples joined";

    // One measured sample alone is still a dot.
    std::vector<double> one(1000, nan);
    one[500] = 0.5;
    panels[1].series = {{"a", one}};
    panels.resize(2);
    ASSERT_TRUE(app::writeLinePlot(dir / "q.png", {panels[1]}, "frame").ok());
    auto q = readImageU8(dir / "q.png", 3);
    ASSERT_TRUE(q.ok()) << q.message();
    EXPECT_GE(pixelsOf(*q, 214, 39, 40), 9u);
}
