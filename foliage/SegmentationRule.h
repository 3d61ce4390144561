#pragma once
// The seasonal treetop rule, per texel, on 8-bit colour: the one definition the CPU segmentation (Segmentation.h,
// OpenCV) and the GPU (shaders/foliage_rule.glsl, which mirrors every constant and function here with the same
// integer arithmetic) share. SegmentationRuleTest checks that the GLSL constants equal these; FoliageRuleGLTest
// runs the GLSL functions on a GPU and compares them with these.
//
// Methods (selected by name everywhere: CLI, renderer, tests):
//  - pixel:        maxchannel(leaf-on) = g and maxchannel(leaf-off) != g (Ropinski et al. 2007 §4.1).
//  - neighborhood: both conditions voted over the k×k neighbourhood, each needing a majority (> k²/2) (§4.1).
//  - equalized:    neighborhood on per-image, per-channel histogram-equalised colour (§4.1, the colour transform).
//  - default:      a texel is canopy when the greenness drop ExG(leaf-on) - ExG(leaf-off) exceeds a threshold taken
//                  from the image pair (Otsu) and the leaf-on canopy is textured (coefficient of variation of the
//                  3×3-smoothed brightness over 5×5 texels > 0.03); that per-texel decision is voted over k×k.
//                  See foliage/README.md for why it beats equalized.
// Pixels outside the image take the value of the nearest edge pixel (GL_CLAMP_TO_EDGE) for every method.
#include <array>
#include <cstdint>
#include <optional>
#include <string_view>

namespace seasonview {

enum class SegmentationMethod { Pixel, Neighborhood, Equalized, Default };

inline constexpr std::array<std::string_view, 4> kSegmentationMethodNames = {"pixel", "neighborhood", "equalized",
                                                                            "default"};

constexpr std::string_view segmentationMethodName(SegmentationMethod m) { return kSegmentationMethodNames[size_t(m)]; }

/// The method called `name` (one of kSegmentationMethodNames), nothing for any other name.
constexpr std::optional<SegmentationMethod> parseSegmentationMethod(std::string_view name) {
    for (size_t i = 0; i < kSegmentationMethodNames.size(); ++i)
        if (kSegmentationMethodNames[i] == name) return SegmentationMethod(i);
    return std::nullopt;
}

// ---- Constants (mirrored as `const int SV_SEG_...` in shaders/foliage_rule.glsl) ----

/// Default and largest neighbourhood size k (odd). 15² = 225 votes still fit the 8-bit vote counters.
constexpr int kSegDefaultK = 5;
constexpr int kSegMaxK = 15;
/// Greenness drop (ExG on - ExG off, in [-3, 3]) is compared in units of 1/kSegDropScale.
constexpr int kSegDropScale = 256;
/// Histogram of the drop for the data-derived threshold: bins of 1/256 over [-1, 1), outer bins clamped.
constexpr int kSegDropBins = 512;
/// The threshold never goes below 13/256 (about 0.05): a smaller drop is no loss of foliage, whatever the histogram.
constexpr int kSegMinDrop = 13;
/// Canopy texture: coefficient of variation of the kSegTexturePrefilter² box-smoothed brightness r+g+b over
/// kSegTextureWindow² texels above sqrt(kSegTextureNum / kSegTextureDen) = 0.03. The prefilter removes texture finer
/// than ~3 texels (crop rows, mown stripes) and keeps that of crowns (leaf clumps, lit and shaded sides).
constexpr int kSegTexturePrefilter = 3;
constexpr int kSegTextureWindow = 5;
constexpr int kSegTextureNum = 9;
constexpr int kSegTextureDen = 10000;
/// Halo (texels beyond the output on each side) the default method's texture needs before its vote.
constexpr int kSegTextureHalo = kSegTexturePrefilter / 2 + kSegTextureWindow / 2;
/// Texels count as data when both seasons cover at least this much of them (alpha of 255); elsewhere no treetop.
constexpr int kSegMinAlpha = 128;

// ---- Premultiplied imagery (pyramids and clipmaps store colour times coverage) ----

/// The colour of a premultiplied 8-bit component `c` whose coverage `a` is partial (0 < a < 255, a coarser level at a
/// data edge): round(c · 255 / a), at most 255; unchanged where a is 0 or 255, so texels with all their data are
/// exactly as stored. Integer arithmetic, the same on the GPU (svUnpremultiply).
constexpr int unpremultiply(int c, int a) {
    return a > 0 && a < 255 ? ((c * 255 + a / 2) / a > 255 ? 255 : (c * 255 + a / 2) / a) : c;
}

// ---- Per-texel rule. r, g, b are 8-bit samples (0..255) after the stretch / equalisation LUT. ----

/// maxchannel(c) = g (§4.1): green strictly brighter than red and blue; ties (grey) are not green.
constexpr bool greenIsMax(int r, int g, int b) { return g > r && g > b; }

/// A vote count of a k×k neighbourhood is a majority: more than half of k² (§4.1: |{...}| > k²/2).
constexpr bool isMajority(int count, int k) { return 2 * count > k * k; }

/// Excess green chromaticity ExG = (2g - r - b) / (r + g + b + 1) as numerator and (positive) denominator.
constexpr int exgNumerator(int r, int g, int b) { return 2 * g - r - b; }
constexpr int exgDenominator(int r, int g, int b) { return r + g + b + 1; }

/// True when ExG(on) - ExG(off) >= t / kSegDropScale, in exact integer arithmetic (|products| < 2^31).
constexpr bool dropAtLeast(int rOn, int gOn, int bOn, int rOff, int gOff, int bOff, int t) {
    const int dOn = exgDenominator(rOn, gOn, bOn), dOff = exgDenominator(rOff, gOff, bOff);
    const int num = exgNumerator(rOn, gOn, bOn) * dOff - exgNumerator(rOff, gOff, bOff) * dOn;
    return kSegDropScale * num >= t * dOn * dOff;
}

/// Histogram bin of the drop: floor(kSegDropScale * drop) + kSegDropBins / 2, clamped to [0, kSegDropBins).
/// dropAtLeast(..., t) is true exactly when dropBin(...) >= t + kSegDropBins / 2 (for bins inside the range).
constexpr int dropBin(int rOn, int gOn, int bOn, int rOff, int gOff, int bOff) {
    const int dOn = exgDenominator(rOn, gOn, bOn), dOff = exgDenominator(rOff, gOff, bOff);
    const int num = kSegDropScale * (exgNumerator(rOn, gOn, bOn) * dOff - exgNumerator(rOff, gOff, bOff) * dOn);
    const int den = dOn * dOff;
    const int q = num >= 0 ? num / den : -((-num + den - 1) / den); // floor division
    const int bin = q + kSegDropBins / 2;
    return bin < 0 ? 0 : bin >= kSegDropBins ? kSegDropBins - 1 : bin;
}

/// Canopy texture test on a window of n smoothed brightness values with sum `sum` and sum of squares `sumSq`:
/// standard deviation > 0.03 × mean, i.e. kSegTextureDen (n·sumSq - sum²) > kSegTextureNum · sum², rearranged to
/// kSegTextureDen · n · sumSq > (kSegTextureDen + kSegTextureNum) · sum². In double: with n <= 25, sum <= 25·6885 and
/// sumSq <= 25·6885² every product is an integer below 2^53, so the test is exact (and vectorises, which 64-bit
/// integer products do not).
constexpr bool textured(double n, double sum, double sumSq) {
    return double(kSegTextureDen) * n * sumSq > double(kSegTextureDen + kSegTextureNum) * sum * sum;
}

/// The default method's per-texel decision before the vote: a large enough greenness drop on a textured canopy.
constexpr bool defaultTexel(bool dropAboveThreshold, bool isTextured) { return dropAboveThreshold && isTextured; }

} // namespace seasonview
