#pragma once
// CPU segmentation of deciduous treetops from a registered leaf-on / leaf-off pair (Ropinski et al. 2007 §4.1), the
// rule of SegmentationRule.h evaluated with OpenCV box filters (integer sums, so every result is exact and does not
// depend on how the image is split), parallel over rows. Works on any band of rows given enough rows around it
// (segmentationHalo), so images larger than memory are segmented band by band (SegmentFiles.h); a band's result is
// identical to the same rows of the whole image.
#include "Raster.h"
#include "SegmentationRule.h"
#include "SegmentationStats.h"

#include <cstdint>

namespace seasonview {

struct SegmentationParams {
    SegmentationMethod method = SegmentationMethod::Default;
    int k = kSegDefaultK; // neighbourhood size, odd, 1..kSegMaxK; `pixel` ignores it (always 1)
};

/// The neighbourhood size `params` really uses (1 for `pixel`).
int effectiveK(const SegmentationParams& params);

/// Rows of input each output row depends on, above and below (pixels: likewise left and right).
int segmentationHalo(const SegmentationParams& params);

/// Rows of an image pair held in memory: interleaved 8-bit RGB (3 bytes per pixel, rows `width` pixels apart),
/// image rows [row0, row0 + rows) of an image `imageHeight` rows high.
struct RgbRows {
    const std::uint8_t* on = nullptr;
    const std::uint8_t* off = nullptr;
    int width = 0, imageHeight = 0, row0 = 0, rows = 0;
    /// rows × width bytes, 0 where either season has no data (nullptr: both have data everywhere). The histograms
    /// skip those pixels; segmentRows evaluates them like any other (callers mark them as no data).
    const std::uint8_t* valid = nullptr;
};

/// A pair of premultiplied RGBA rows (pyramid level 0, whose alpha is 0 or 255) split into RGB and `valid` (255 where
/// both seasons have data, else 0), n pixels. Returns true when every pixel is valid.
bool splitPairRgba(const std::uint8_t* onRgba, const std::uint8_t* offRgba, size_t n, std::uint8_t* onRgb,
                   std::uint8_t* offRgb, std::uint8_t* valid);

/// Segments image rows [outRow0, outRow0 + outRows) into `mask` (outRows × width bytes, 255 = treetop, 0 = not).
/// `in` must hold every image row within segmentationHalo(params) of the output rows (rows outside the image are
/// the edge rows repeated, as with GL_CLAMP_TO_EDGE). `stats` comes from the whole pair (statsFromHistograms) or is
/// default-constructed for pixel/neighborhood. Parallel over rows on OpenCV's threads.
void segmentRows(const RgbRows& in, int outRow0, int outRows, const SegmentationParams& params,
                 const SegmentationStats& stats, std::uint8_t* mask);

/// The pair statistics sample every kSegHistogramStep-th pixel of every kSegHistogramStep-th row (image rows and
/// columns divisible by it): a quarter of the work for histograms of millions of samples all the same.
constexpr int kSegHistogramStep = 2;

/// Histograms of the sampled pixels of `in` (colour: per-channel tables for `equalized`, drop: for `default`),
/// parallel over rows; a whole pair's are the merge of its bands' (SegmentationHistograms::merge).
SegmentationHistograms rowHistograms(const RgbRows& in, bool colour, bool drop);

/// Histograms of a whole pair held in memory (both images width × height RGB), parallel over rows.
SegmentationHistograms pairHistograms(const Image<std::uint8_t>& on, const Image<std::uint8_t>& off, bool colour,
                                      bool drop);

/// The whole-image segmentation of an in-memory pair (both RGB, same size): stats from the pair's own histograms,
/// then every row at once. The reference the banded path (SegmentFiles.h) must reproduce byte for byte.
Image<std::uint8_t> segmentImage(const Image<std::uint8_t>& on, const Image<std::uint8_t>& off,
                                 const SegmentationParams& params);

} // namespace seasonview
