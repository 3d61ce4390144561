#pragma once
// What the segmentation rule needs from a whole image pair besides its texels: the per-image, per-channel histogram
// equalisation lookup tables (method `equalized`) and the data-derived greenness-drop threshold (method `default`).
// Computed once per pair from histograms (on the GPU: once per layer when the pyramid is prepared), then applied
// per texel. Plain C++, no OpenCV.
#include "SegmentationRule.h"

#include <array>
#include <cstddef>
#include <cstdint>

namespace seasonview {

using ChannelLut = std::array<std::uint8_t, 256>;
using ChannelHistogram = std::array<std::uint64_t, 256>;

/// Histograms of an image pair, accumulated row band by row band (8-bit RGB after the 16-bit stretch).
struct SegmentationHistograms {
    std::array<ChannelHistogram, 3> on{}, off{};            // per channel of each season
    std::array<std::uint64_t, kSegDropBins> drop{};         // dropBin() of every pixel pair

    /// Adds `pixels` interleaved RGB pixel pairs to the per-channel histograms (`colour`) and to the drop histogram
    /// (`withDrop`), all of them: the reference for the sampled, vectorised rowHistograms() of Segmentation.h.
    void add(const std::uint8_t* onRgb, const std::uint8_t* offRgb, std::size_t pixels, bool colour, bool withDrop);
    /// Adds another set of histograms (per-thread partial sums).
    void merge(const SegmentationHistograms& other);
};

/// Everything per pair the per-texel rule uses. Default-constructed: identity tables, threshold kSegMinDrop.
struct SegmentationStats {
    std::array<ChannelLut, 3> lutOn, lutOff; // colour lookup per channel (identity unless `equalized`)
    int dropThreshold = kSegMinDrop;         // default method: drop >= dropThreshold / kSegDropScale
    SegmentationStats();
};

/// Histogram equalisation table of one channel: lut[v] = round(255 (cdf(v) - cdf_min) / (N - cdf_min)), cdf_min being
/// the count of the darkest value present; v below it maps to 0. An empty or one-valued histogram gives identity.
ChannelLut equalizationLut(const ChannelHistogram& histogram);

/// Otsu's threshold of a histogram: the bin t maximising the between-class variance of [0, t] against
/// [t + 1, bins); the first such t on ties. 0 for an empty histogram or one with a single occupied bin.
int otsuThreshold(const std::uint64_t* histogram, int bins);

/// The greenness-drop threshold (units of 1/kSegDropScale) of a drop histogram: the lower edge of the upper Otsu
/// class, never below kSegMinDrop.
int dropThresholdFromHistogram(const std::array<std::uint64_t, kSegDropBins>& drop);

/// Whether `method` needs the histograms of the whole pair before it can segment a texel.
constexpr bool needsHistograms(SegmentationMethod method) {
    return method == SegmentationMethod::Equalized || method == SegmentationMethod::Default;
}

/// The stats of `method` from histograms of the whole pair (tables for equalized, threshold for default).
SegmentationStats statsFromHistograms(const SegmentationHistograms& histograms, SegmentationMethod method);

} // namespace seasonview
