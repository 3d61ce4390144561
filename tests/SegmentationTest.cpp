// The seasonal treetop segmentation (foliage/): the per-texel rule, its CPU implementation against a brute-force
// reference and hand-made images with known answers, banded == whole, the pair statistics, the scores and the crown
// centres. No GL; files only for the true-tree CSV.
#include "CrownCentres.h"
#include "SegmentFiles.h"
#include "Segmentation.h"
#include "SegmentationMetrics.h"
#include "SegmentationRule.h"
#include "SegmentationStats.h"
#include "TestUtil.h"
#include "gl/ShaderProgram.h"

#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <random>
#include <regex>
#include <sstream>

using namespace seasonview;
using namespace seasonview::test;

namespace {

constexpr SegmentationMethod kAllMethods[] = {SegmentationMethod::Pixel, SegmentationMethod::Neighborhood,
                                              SegmentationMethod::Equalized, SegmentationMethod::Default};

Image<std::uint8_t> solid(int w, int h, int r, int g, int b) {
    Image<std::uint8_t> img;
    img.width = w;
    img.height = h;
    img.channels = 3;
    img.pixels.resize(size_t(w) * size_t(h) * 3);
    for (size_t i = 0; i < img.pixels.size(); i += 3) {
        img.pixels[i] = std::uint8_t(r);
        img.pixels[i + 1] = std::uint8_t(g);
        img.pixels[i + 2] = std::uint8_t(b);
    }
    return img;
}

void paint(Image<std::uint8_t>& img, int x, int y, int r, int g, int b) {
    img.at(x, y, 0) = std::uint8_t(r);
    img.at(x, y, 1) = std::uint8_t(g);
    img.at(x, y, 2) = std::uint8_t(b);
}

Image<std::uint8_t> noiseImage(int w, int h, unsigned seed) {
    Image<std::uint8_t> img = solid(w, h, 0, 0, 0);
    std::mt19937 rng(seed);
    for (auto& v : img.pixels) v = std::uint8_t(rng() & 0xFF);
    return img;
}

SegmentationStats statsOf(const Image<std::uint8_t>& on, const Image<std::uint8_t>& off, SegmentationMethod m) {
    if (!needsHistograms(m)) return SegmentationStats{};
    return statsFromHistograms(pairHistograms(on, off, m == SegmentationMethod::Equalized,
                                              m == SegmentationMethod::Default),
                               m);
}

// The rule straight from SegmentationRule.h, pixel by pixel, on the image extended by repeating its edge pixels:
// no sums shared between pixels, no bands, no padding tricks.
Image<std::uint8_t> referenceMask(const Image<std::uint8_t>& on, const Image<std::uint8_t>& off,
                                  const SegmentationParams& params, const SegmentationStats& st) {
    const int w = on.width, h = on.height, k = effectiveK(params), half = k / 2;
    auto px = [&](const Image<std::uint8_t>& img, int x, int y, int c) {
        return int(img.at(std::clamp(x, 0, w - 1), std::clamp(y, 0, h - 1), c));
    };
    auto onGreen = [&](int x, int y) {
        return greenIsMax(st.lutOn[0][size_t(px(on, x, y, 0))], st.lutOn[1][size_t(px(on, x, y, 1))],
                          st.lutOn[2][size_t(px(on, x, y, 2))]);
    };
    auto offGreen = [&](int x, int y) {
        return greenIsMax(st.lutOff[0][size_t(px(off, x, y, 0))], st.lutOff[1][size_t(px(off, x, y, 1))],
                          st.lutOff[2][size_t(px(off, x, y, 2))]);
    };
    auto smooth = [&](int x, int y) { // 3×3 sum of the leaf-on brightness
        int s = 0;
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx)
                s += px(on, x + dx, y + dy, 0) + px(on, x + dx, y + dy, 1) + px(on, x + dx, y + dy, 2);
        return s;
    };
    auto defaultBit = [&](int x, int y) {
        const bool drop = dropAtLeast(px(on, x, y, 0), px(on, x, y, 1), px(on, x, y, 2), px(off, x, y, 0),
                                      px(off, x, y, 1), px(off, x, y, 2), st.dropThreshold);
        double a = 0, q = 0;
        for (int dy = -2; dy <= 2; ++dy)
            for (int dx = -2; dx <= 2; ++dx) {
                const double v = smooth(x + dx, y + dy);
                a += v;
                q += v * v;
            }
        return defaultTexel(drop, textured(25, a, q));
    };
    Image<std::uint8_t> mask = solid(w, h, 0, 0, 0);
    mask.channels = 1;
    mask.pixels.assign(size_t(w) * size_t(h), 0);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            int a = 0, b = 0;
            for (int dy = -half; dy <= half; ++dy)
                for (int dx = -half; dx <= half; ++dx) {
                    if (params.method == SegmentationMethod::Default) {
                        a += defaultBit(x + dx, y + dy);
                    } else {
                        a += onGreen(x + dx, y + dy);
                        b += !offGreen(x + dx, y + dy);
                    }
                }
            const bool tree = params.method == SegmentationMethod::Default ? isMajority(a, k)
                                                                           : isMajority(a, k) && isMajority(b, k);
            mask.at(x, y) = tree ? 255 : 0;
        }
    return mask;
}

// The whole image segmented band by band, each band given only the rows within the halo (the banded path of
// SegmentFiles.cpp, in memory).
std::vector<std::uint8_t> segmentBanded(const Image<std::uint8_t>& on, const Image<std::uint8_t>& off,
                                        const SegmentationParams& params, const SegmentationStats& st, int bandRows) {
    const int w = on.width, h = on.height, halo = segmentationHalo(params);
    std::vector<std::uint8_t> mask(size_t(w) * size_t(h));
    for (int y0 = 0; y0 < h; y0 += bandRows) {
        const int y1 = std::min(h, y0 + bandRows), first = std::max(0, y0 - halo), last = std::min(h, y1 + halo);
        // Copies, so that rows outside the window cannot be read by accident.
        std::vector<std::uint8_t> a(on.pixels.begin() + std::ptrdiff_t(first) * w * 3,
                                    on.pixels.begin() + std::ptrdiff_t(last) * w * 3);
        std::vector<std::uint8_t> b(off.pixels.begin() + std::ptrdiff_t(first) * w * 3,
                                    off.pixels.begin() + std::ptrdiff_t(last) * w * 3);
        segmentRows(RgbRows{a.data(), b.data(), w, h, first, last - first}, y0, y1 - y0, params, st,
                    mask.data() + size_t(y0) * size_t(w));
    }
    return mask;
}

double crownScore(const Image<std::uint8_t>& mask, const Image<std::uint8_t>& truth) {
    Confusion c;
    c.add(mask.pixels.data(), truth.pixels.data(), mask.pixels.size());
    return c.f1();
}

} // namespace

// ---- The rule ----

TEST(SegmentationRuleTest, MethodNamesRoundTrip) {
    for (SegmentationMethod m : kAllMethods) EXPECT_EQ(parseSegmentationMethod(segmentationMethodName(m)), m);
    EXPECT_EQ(segmentationMethodName(SegmentationMethod::Default), "default");
    EXPECT_FALSE(parseSegmentationMethod("Pixel").has_value());
    EXPECT_FALSE(parseSegmentationMethod("").has_value());
}

TEST(SegmentationRuleTest, GreenIsMaxAndMajority) {
    EXPECT_TRUE(greenIsMax(10, 11, 10));
    EXPECT_FALSE(greenIsMax(11, 11, 10)) << "a tie with red is not green";
    EXPECT_FALSE(greenIsMax(10, 11, 11)) << "a tie with blue is not green";
    EXPECT_FALSE(greenIsMax(0, 0, 0));
    EXPECT_TRUE(isMajority(5, 3));
    EXPECT_FALSE(isMajority(4, 3));
    EXPECT_TRUE(isMajority(13, 5));
    EXPECT_FALSE(isMajority(12, 5));
    EXPECT_TRUE(isMajority(1, 1));
    EXPECT_FALSE(isMajority(0, 1));
}

TEST(SegmentationRuleTest, DropTestIsExactAndAgreesWithBins) {
    std::mt19937 rng(5);
    for (int i = 0; i < 200000; ++i) {
        int c[6];
        for (int& v : c) v = int(rng() % 256);
        const double exact = double(2 * c[1] - c[0] - c[2]) / (c[0] + c[1] + c[2] + 1) -
                             double(2 * c[4] - c[3] - c[5]) / (c[3] + c[4] + c[5] + 1);
        const int t = int(rng() % 511) - 255;
        const bool drop = dropAtLeast(c[0], c[1], c[2], c[3], c[4], c[5], t);
        if (std::abs(exact * kSegDropScale - t) > 1e-9) {
            ASSERT_EQ(drop, exact * kSegDropScale >= t) << i;
        }
        const int bin = dropBin(c[0], c[1], c[2], c[3], c[4], c[5]);
        ASSERT_EQ(drop, bin >= t + kSegDropBins / 2) << i;
        ASSERT_EQ(bin, std::clamp(int(std::floor(exact * kSegDropScale + 1e-12)) + kSegDropBins / 2, 0,
                                  kSegDropBins - 1))
            << i;
    }
    // Extremes: pure green to black, black to pure green.
    EXPECT_EQ(dropBin(0, 255, 0, 0, 0, 0), kSegDropBins - 1);
    EXPECT_EQ(dropBin(0, 0, 0, 0, 255, 0), 0);
}

TEST(SegmentationRuleTest, TextureTest) {
    // 25 equal values: no variation.
    EXPECT_FALSE(textured(25, 25 * 1000.0, 25 * 1000.0 * 1000.0));
    // Half at 1000 - d, half at 1000 + d (25 values: 12, 12 and one at 1000): std = d sqrt(24/25), mean 1000.
    auto window = [](double d) {
        const double sum = 12 * (1000 - d) + 12 * (1000 + d) + 1000;
        const double sumSq = 12 * (1000 - d) * (1000 - d) + 12 * (1000 + d) * (1000 + d) + 1000.0 * 1000.0;
        return textured(25, sum, sumSq);
    };
    EXPECT_FALSE(window(30.0)); // std 29.4 < 0.03 × 1000
    EXPECT_TRUE(window(31.0));  // std 30.4 > 30
}

// The GPU copy of the rule (shaders/foliage_rule.glsl) declares exactly the C++ constants, with the same values.
TEST(SegmentationRuleTest, GlslConstantsEqualCpp) {
    const std::string glsl = gl::shaderSource("foliage_rule.glsl");
    ASSERT_FALSE(glsl.empty()) << "foliage_rule.glsl is not embedded";
    const std::map<std::string, int> cpp = {{"SV_SEG_DEFAULT_K", kSegDefaultK},
                                            {"SV_SEG_MAX_K", kSegMaxK},
                                            {"SV_SEG_DROP_SCALE", kSegDropScale},
                                            {"SV_SEG_DROP_BINS", kSegDropBins},
                                            {"SV_SEG_MIN_DROP", kSegMinDrop},
                                            {"SV_SEG_TEXTURE_PREFILTER", kSegTexturePrefilter},
                                            {"SV_SEG_TEXTURE_WINDOW", kSegTextureWindow},
                                            {"SV_SEG_TEXTURE_NUM", kSegTextureNum},
                                            {"SV_SEG_TEXTURE_DEN", kSegTextureDen},
                                            {"SV_SEG_TEXTURE_HALO", kSegTextureHalo},
                                            {"SV_SEG_MIN_ALPHA", kSegMinAlpha}};
    std::map<std::string, int> parsed;
    const std::regex line(R"(^\s*const\s+int\s+(SV_SEG_\w+)\s*=\s*(-?\d+)\s*;)");
    std::istringstream in(glsl);
    for (std::string l; std::getline(in, l);) {
        std::smatch m;
        if (std::regex_search(l, m, line)) parsed[m[1].str()] = std::stoi(m[2].str());
    }
    EXPECT_EQ(parsed, cpp);
}

// ---- Known answers on hand-made images ----

TEST(SegmentationTest, PixelKnownAnswers) {
    // Four pixels: green -> grey (tree), green -> green (evergreen), grey -> grey, red -> grey.
    Image<std::uint8_t> on = solid(4, 1, 0, 0, 0), off = solid(4, 1, 0, 0, 0);
    paint(on, 0, 0, 40, 90, 30);
    paint(off, 0, 0, 90, 85, 80);
    paint(on, 1, 0, 40, 90, 30);
    paint(off, 1, 0, 40, 70, 35);
    paint(on, 2, 0, 90, 90, 90);
    paint(off, 2, 0, 90, 90, 90);
    paint(on, 3, 0, 120, 60, 50);
    paint(off, 3, 0, 90, 85, 80);
    const Image<std::uint8_t> mask = segmentImage(on, off, {SegmentationMethod::Pixel, 7}); // pixel ignores k
    EXPECT_EQ(mask.pixels, (std::vector<std::uint8_t>{255, 0, 0, 0}));
}

TEST(SegmentationTest, NeighborhoodNeedsAMajorityOfBothConditions) {
    // 3×3, k = 3: the centre's neighbourhood is the whole image. Leaf-off is grey (not green) everywhere.
    for (int green = 0; green <= 9; ++green) {
        Image<std::uint8_t> on = solid(3, 3, 90, 80, 70), off = solid(3, 3, 90, 85, 80);
        for (int i = 0; i < green; ++i) paint(on, i % 3, i / 3, 40, 90, 30);
        const Image<std::uint8_t> mask = segmentImage(on, off, {SegmentationMethod::Neighborhood, 3});
        EXPECT_EQ(mask.at(1, 1), green >= 5 ? 255 : 0) << green << " of 9 green";
    }
    // All green in leaf-on, but 5 of 9 leaf-off texels still green: the leaf-off majority fails.
    Image<std::uint8_t> on = solid(3, 3, 40, 90, 30), off = solid(3, 3, 90, 85, 80);
    for (int i = 0; i < 5; ++i) paint(off, i % 3, i / 3, 40, 70, 35);
    EXPECT_EQ(segmentImage(on, off, {SegmentationMethod::Neighborhood, 3}).at(1, 1), 0);
    // The pixel rule sees the four texels where both hold.
    const Image<std::uint8_t> pixel = segmentImage(on, off, {SegmentationMethod::Pixel, 3});
    EXPECT_EQ(std::count(pixel.pixels.begin(), pixel.pixels.end(), 255), 4);
}

TEST(SegmentationTest, BorderRepeatsEdgePixels) {
    // 5×4, k = 3, only column 0 green in leaf-on. With edge repetition the left column's neighbourhood holds column 0
    // twice (6 of 9 green: a tree); a zero-padded or shrunk window would not give 6 of 9, and column 1 sees 3 of 9.
    Image<std::uint8_t> on = solid(5, 4, 90, 80, 70), off = solid(5, 4, 90, 85, 80);
    for (int y = 0; y < 4; ++y) paint(on, 0, y, 40, 90, 30);
    const Image<std::uint8_t> mask = segmentImage(on, off, {SegmentationMethod::Neighborhood, 3});
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 5; ++x) EXPECT_EQ(mask.at(x, y), x == 0 ? 255 : 0) << x << "," << y;
    // k larger than the image: at x = 0 the columns -3..3 are 0,0,0,0,1,2,3 (four copies of the green column: 28
    // of 49 votes), at x = 1 three copies (21 of 49).
    const Image<std::uint8_t> wide = segmentImage(on, off, {SegmentationMethod::Neighborhood, 7});
    EXPECT_EQ(wide.at(0, 0), 255);
    EXPECT_EQ(wide.at(1, 0), 0);
    EXPECT_EQ(wide.at(0, 3), 255);
}

TEST(SegmentationTest, EqualizationLutKnownHistogram) {
    ChannelHistogram h{};
    h[10] = 1, h[20] = 2, h[30] = 1; // cdf 1, 3, 4; cdf_min 1
    const ChannelLut lut = equalizationLut(h);
    EXPECT_EQ(lut[0], 0);
    EXPECT_EQ(lut[10], 0);
    EXPECT_EQ(lut[15], 0);
    EXPECT_EQ(lut[20], 170); // 255 × 2/3
    EXPECT_EQ(lut[29], 170);
    EXPECT_EQ(lut[30], 255);
    EXPECT_EQ(lut[255], 255);
    // Uniform over all 256 values: identity.
    ChannelHistogram u;
    u.fill(7);
    const ChannelLut id = equalizationLut(u);
    for (int v = 0; v < 256; ++v) EXPECT_EQ(id[size_t(v)], v);
    // Empty or one value: identity (nothing to spread).
    ChannelHistogram one{};
    one[77] = 100;
    EXPECT_EQ(equalizationLut(one)[77], 77);
    EXPECT_EQ(equalizationLut(ChannelHistogram{})[200], 200);
    // Monotonic on real data.
    const TreePair p = makeTreePair(64, 48);
    const SegmentationStats st = statsOf(p.on, p.off, SegmentationMethod::Equalized);
    for (const auto& l : st.lutOn)
        for (int v = 1; v < 256; ++v) EXPECT_LE(l[size_t(v - 1)], l[size_t(v)]);
}

TEST(SegmentationTest, EqualizedKnownAnswer) {
    // Four colours, each a 2×2 block (so that the histogram sample, every second pixel of every second row, holds
    // each once). Block 0 is red-dominated as recorded, but its green is the brightest green of the image while its
    // blue is the darkest blue: equalised it is (170, 255, 0), green. The others equalise to (0, 0, 85),
    // (85, 85, 170), (255, 170, 255). Leaf-off is one grey: a one-valued histogram keeps it as it is, not green.
    const int colours[4][3] = {{120, 105, 80}, {100, 90, 120}, {110, 95, 130}, {130, 100, 140}};
    Image<std::uint8_t> on = solid(8, 2, 0, 0, 0), off = solid(8, 2, 90, 85, 80);
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 8; ++x) paint(on, x, y, colours[x / 2][0], colours[x / 2][1], colours[x / 2][2]);
    const SegmentationStats st = statsOf(on, off, SegmentationMethod::Equalized);
    EXPECT_EQ(st.lutOn[0][120], 170);
    EXPECT_EQ(st.lutOn[1][105], 255);
    EXPECT_EQ(st.lutOn[2][80], 0);
    const std::vector<std::uint8_t> expected = {255, 255, 0, 0, 0, 0, 0, 0, 255, 255, 0, 0, 0, 0, 0, 0};
    EXPECT_EQ(segmentImage(on, off, {SegmentationMethod::Equalized, 1}).pixels, expected);
    EXPECT_EQ(segmentImage(on, off, {SegmentationMethod::Neighborhood, 1}).pixels, std::vector<std::uint8_t>(16, 0));
}

TEST(SegmentationTest, EqualizedIsNeighborhoodOnEqualizedColour) {
    const TreePair p = makeTreePair(64, 48, 3);
    const SegmentationStats st = statsOf(p.on, p.off, SegmentationMethod::Equalized);
    Image<std::uint8_t> on = p.on, off = p.off;
    for (size_t i = 0; i < on.pixels.size(); ++i) {
        on.pixels[i] = st.lutOn[i % 3][on.pixels[i]];
        off.pixels[i] = st.lutOff[i % 3][off.pixels[i]];
    }
    for (int k : {1, 3, 5})
        EXPECT_EQ(segmentImage(p.on, p.off, {SegmentationMethod::Equalized, k}).pixels,
                  segmentBanded(on, off, {SegmentationMethod::Neighborhood, k}, SegmentationStats{}, 1000))
            << k;
}

TEST(SegmentationTest, OtsuThresholdSplitsModes) {
    std::uint64_t h[10] = {0, 5, 9, 5, 0, 0, 0, 4, 8, 4};
    EXPECT_EQ(otsuThreshold(h, 10), 3); // [0, 3] | [4, 9]: any t in 3..6 splits the modes, the first wins
    std::uint64_t flat[4] = {0, 0, 12, 0};
    EXPECT_EQ(otsuThreshold(flat, 4), 0);
    std::uint64_t none[4] = {0, 0, 0, 0};
    EXPECT_EQ(otsuThreshold(none, 4), 0);
    // The drop threshold is the lower edge of the upper class, and never below kSegMinDrop.
    std::array<std::uint64_t, kSegDropBins> drop{};
    drop[kSegDropBins / 2 + 30] = 100; // drop ~ 0.12
    drop[kSegDropBins / 2 + 90] = 50;  // drop ~ 0.35
    EXPECT_EQ(dropThresholdFromHistogram(drop), 31);
    drop.fill(0);
    drop[kSegDropBins / 2 + 2] = 100;
    drop[kSegDropBins / 2 + 5] = 50;
    EXPECT_EQ(dropThresholdFromHistogram(drop), kSegMinDrop);
}

TEST(SegmentationTest, DefaultFindsCrownsAndIgnoresTheCropField) {
    const TreePair p = makeTreePair(96, 64);
    const Image<std::uint8_t> def = segmentImage(p.on, p.off, {SegmentationMethod::Default, 5});
    const Image<std::uint8_t> nbh = segmentImage(p.on, p.off, {SegmentationMethod::Neighborhood, 5});
    EXPECT_GT(crownScore(def, p.truth), 0.85);
    EXPECT_LT(crownScore(nbh, p.truth), 0.6) << "the crop field turns brown too: a false positive for §4.1";
    // Nothing in the crop field, nothing on the meadow away from the crowns.
    const int cropX = 96 * 2 / 3;
    for (int y = 0; y < 64; ++y)
        for (int x = 0; x < 96; ++x) {
            bool nearCrown = false;
            for (const auto& c : p.crowns) nearCrown |= std::hypot(x + 0.5 - c[0], y + 0.5 - c[1]) < c[2] + 4.0;
            if (!nearCrown && std::abs(x - cropX) > 4) {
                ASSERT_EQ(def.at(x, y), 0) << x << "," << y;
            }
        }
    // Every crown centre is found.
    for (const auto& c : p.crowns) EXPECT_EQ(def.at(int(c[0]), int(c[1])), 255);
}

// ---- The implementation against the brute-force reference, and banded == whole ----

TEST(SegmentationTest, MatchesBruteForceReference) {
    struct Case {
        Image<std::uint8_t> on, off;
    };
    std::vector<Case> cases;
    const TreePair a = makeTreePair(37, 29, 1), b = makeTreePair(24, 40, 2);
    cases.push_back({a.on, a.off});
    cases.push_back({b.on, b.off});
    cases.push_back({noiseImage(23, 19, 1), noiseImage(23, 19, 2)});
    cases.push_back({solid(1, 1, 40, 90, 30), solid(1, 1, 90, 85, 80)}); // a single pixel
    cases.push_back({makeTreePair(31, 2).on, makeTreePair(31, 2).off});   // fewer rows than the halo
    std::map<SegmentationMethod, size_t> positives;
    for (const Case& c : cases)
        for (SegmentationMethod m : kAllMethods)
            for (int k : {1, 3, 5, 7}) {
                const SegmentationParams params{m, k};
                const SegmentationStats st = statsOf(c.on, c.off, m);
                const std::vector<std::uint8_t> mask = segmentImage(c.on, c.off, params).pixels;
                ASSERT_EQ(mask, referenceMask(c.on, c.off, params, st).pixels)
                    << segmentationMethodName(m) << " k " << k << " on " << c.on.width << "x" << c.on.height;
                positives[m] += size_t(std::count(mask.begin(), mask.end(), 255));
            }
    for (SegmentationMethod m : kAllMethods)
        EXPECT_GT(positives[m], 100u) << "a comparison of empty masks proves little";
}

TEST(SegmentationTest, BandedEqualsWhole) {
    const TreePair p = makeTreePair(83, 61, 4);
    for (SegmentationMethod m : kAllMethods)
        for (int k : {1, 3, 5, 15}) {
            const SegmentationParams params{m, k};
            const SegmentationStats st = statsOf(p.on, p.off, m);
            const std::vector<std::uint8_t> whole = segmentImage(p.on, p.off, params).pixels;
            for (int band : {1, 2, 7, 16, 60, 61, 200})
                ASSERT_EQ(segmentBanded(p.on, p.off, params, st, band), whole)
                    << segmentationMethodName(m) << " k " << k << " bands of " << band;
        }
}

TEST(SegmentationTest, HistogramsSampleFixedImageRows) {
    const Image<std::uint8_t> on = noiseImage(45, 37, 7), off = noiseImage(45, 37, 8);
    // Brute force: every kSegHistogramStep-th pixel of every kSegHistogramStep-th row.
    SegmentationHistograms expected;
    for (int y = 0; y < 37; y += kSegHistogramStep)
        for (int x = 0; x < 45; x += kSegHistogramStep)
            expected.add(&on.at(x, y, 0), &off.at(x, y, 0), 1, true, true);
    const SegmentationHistograms whole = pairHistograms(on, off, true, true);
    EXPECT_EQ(whole.on, expected.on);
    EXPECT_EQ(whole.off, expected.off);
    EXPECT_EQ(whole.drop, expected.drop);
    // Band by band (odd band heights, so bands start on odd rows) gives the same.
    SegmentationHistograms banded;
    for (int y0 = 0; y0 < 37; y0 += 5) {
        const int y1 = std::min(37, y0 + 5);
        banded.merge(rowHistograms(RgbRows{&on.at(0, y0, 0), &off.at(0, y0, 0), 45, 37, y0, y1 - y0}, true, true));
    }
    EXPECT_EQ(banded.on, expected.on);
    EXPECT_EQ(banded.drop, expected.drop);
}

// ---- Scores ----

TEST(SegmentationMetricsTest, KnownConfusionMatrix) {
    // 100 pixels: tp 6, fp 2, fn 4, tn 88.
    std::vector<std::uint8_t> mask(100, 0), truth(100, 0);
    for (int i = 0; i < 6; ++i) mask[size_t(i)] = truth[size_t(i)] = 255;
    mask[10] = mask[11] = 1; // any non-zero value counts
    for (int i = 20; i < 24; ++i) truth[size_t(i)] = 7;
    Confusion c;
    c.add(mask.data(), truth.data(), 60);
    c.add(mask.data() + 60, truth.data() + 60, 40);
    EXPECT_EQ(c.tp, 6u);
    EXPECT_EQ(c.fp, 2u);
    EXPECT_EQ(c.fn, 4u);
    EXPECT_EQ(c.tn, 88u);
    EXPECT_EQ(c.pixels(), 100u);
    EXPECT_DOUBLE_EQ(c.precision(), 0.75);
    EXPECT_DOUBLE_EQ(c.recall(), 0.6);
    EXPECT_DOUBLE_EQ(c.f1(), 12.0 / 18.0);
    EXPECT_DOUBLE_EQ(c.iou(), 0.5);
    Confusion sum = c;
    sum += c;
    EXPECT_EQ(sum.tp, 12u);
    EXPECT_DOUBLE_EQ(sum.f1(), c.f1());
    // Zero denominators: 0, not NaN.
    const Confusion empty;
    EXPECT_EQ(empty.precision(), 0.0);
    EXPECT_EQ(empty.recall(), 0.0);
    EXPECT_EQ(empty.f1(), 0.0);
    EXPECT_EQ(empty.iou(), 0.0);
}

TEST(SegmentationMetricsTest, CentresMatchOneToOneWithinTheTrueRadius) {
    const std::vector<CrownPoint> truth = {{0, 0, 2.0}, {10, 0, 3.0}, {30, 30, 1.0}};
    const std::vector<CrownPoint> detected = {{0.5, 0, 1}, {0.2, 0.2, 1}, {12.5, 0, 1}, {30, 31.5, 1}, {-50, 0, 1}};
    const CentreScores s = matchCentres(detected, truth);
    // (0,0) matched once (the closer detection); (10,0) by the one 2.5 m away (radius 3); (30,30): 1.5 > 1 m.
    EXPECT_EQ(s.matched, 2);
    EXPECT_EQ(s.detected, 5);
    EXPECT_EQ(s.truth, 3);
    EXPECT_DOUBLE_EQ(s.precision(), 0.4);
    EXPECT_DOUBLE_EQ(s.recall(), 2.0 / 3.0);
    EXPECT_EQ(matchCentres({}, truth).precision(), 0.0);
    EXPECT_EQ(matchCentres(detected, {}).recall(), 0.0);
}

// ---- Crown centres ----

TEST(CrownCentresTest, DiscsGiveTheirCentresAndRadii) {
    const TreePair p = makeTreePair(96, 64, 0);
    CrownParams params;
    params.minRadiusPx = 2.0;
    params.maxRadiusPx = 20;
    const std::vector<CrownDetection> crowns = detectCrowns(p.truth, params);
    ASSERT_EQ(crowns.size(), p.crowns.size());
    for (const auto& c : p.crowns) {
        auto it = std::min_element(crowns.begin(), crowns.end(), [&](const CrownDetection& a, const CrownDetection& b) {
            return std::hypot(a.px - c[0], a.py - c[1]) < std::hypot(b.px - c[0], b.py - c[1]);
        });
        EXPECT_LE(std::hypot(it->px - c[0], it->py - c[1]), 1.0);
        EXPECT_NEAR(it->radiusPx, c[2], 1.0);
    }
    Image<std::uint8_t> empty = p.truth;
    std::fill(empty.pixels.begin(), empty.pixels.end(), 0);
    EXPECT_TRUE(detectCrowns(empty, params).empty());
}

TEST(CrownCentresTest, BandedEqualsWhole) {
    const TreePair p = makeTreePair(120, 90, 6);
    Image<std::uint8_t> mask = segmentImage(p.on, p.off, {SegmentationMethod::Neighborhood, 3});
    CrownParams params;
    params.minRadiusPx = 1.5;
    params.maxRadiusPx = 9; // clamps the larger crowns: the clamp must not make bands differ either
    const std::vector<CrownDetection> whole = detectCrowns(mask, params);
    ASSERT_FALSE(whole.empty());
    const int halo = crownHalo(params);
    for (int band : {1, 5, 17, 90}) {
        std::vector<CrownDetection> banded;
        for (int y0 = 0; y0 < mask.height; y0 += band) {
            const int y1 = std::min(mask.height, y0 + band);
            const int first = std::max(0, y0 - halo), last = std::min(mask.height, y1 + halo);
            detectCrownRows(mask.pixels.data() + size_t(first) * size_t(mask.width), mask.width, mask.height, first,
                            last - first, y0, y1 - y0, params, banded);
        }
        ASSERT_EQ(banded.size(), whole.size()) << band;
        for (size_t i = 0; i < whole.size(); ++i) {
            EXPECT_EQ(banded[i].px, whole[i].px);
            EXPECT_EQ(banded[i].py, whole[i].py);
            EXPECT_EQ(banded[i].radiusPx, whole[i].radiusPx);
        }
    }
}

TEST(CrownCentresTest, TrueTreeCsv) {
    TempDir dir("trees-csv");
    std::ofstream(dir / "trees.csv") << "id,type,x,y,easting,northing,radius_m,height_m\n"
                                        "1,deciduous,1.5,-2.25,0,0,3.0,12\n"
                                        "2,conifer,4,4,0,0,2.0,9\n"
                                        "3,deciduous,-7,8,0,0,4.5,15\n";
    auto trees = readTrueTrees(dir / "trees.csv");
    ASSERT_TRUE(trees.ok()) << trees.message();
    ASSERT_EQ(trees->size(), 2u) << "conifers are not deciduous treetops";
    EXPECT_EQ((*trees)[0].x, 1.5);
    EXPECT_EQ((*trees)[0].y, -2.25);
    EXPECT_EQ((*trees)[1].radiusM, 4.5);
    std::ofstream(dir / "bad.csv") << "x,y,radius_m\n1,2,3\n1,2x,3\n";
    auto bad = readTrueTrees(dir / "bad.csv");
    ASSERT_FALSE(bad.ok());
    EXPECT_NE(bad.message().find("bad.csv: line 3: x, y and radius_m must be numbers"), std::string::npos)
        << bad.message();
    std::ofstream(dir / "cols.csv") << "id,x,y\n";
    EXPECT_NE(readTrueTrees(dir / "cols.csv").message().find("header needs columns x, y and radius_m"),
              std::string::npos);
}
