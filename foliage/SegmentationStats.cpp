#include "SegmentationStats.h"

#include <cmath>

namespace seasonview {

void SegmentationHistograms::add(const std::uint8_t* onRgb, const std::uint8_t* offRgb, std::size_t pixels,
                                 bool colour, bool withDrop) {
    if (colour)
        for (std::size_t i = 0; i < pixels; ++i)
            for (std::size_t c = 0; c < 3; ++c) {
                ++on[c][onRgb[i * 3 + c]];
                ++off[c][offRgb[i * 3 + c]];
            }
    if (withDrop)
        for (std::size_t i = 0; i < pixels; ++i) {
            const std::uint8_t* a = onRgb + i * 3;
            const std::uint8_t* b = offRgb + i * 3;
            ++drop[size_t(dropBin(a[0], a[1], a[2], b[0], b[1], b[2]))];
        }
}

void SegmentationHistograms::merge(const SegmentationHistograms& other) {
    for (size_t c = 0; c < 3; ++c)
        for (size_t v = 0; v < 256; ++v) {
            on[c][v] += other.on[c][v];
            off[c][v] += other.off[c][v];
        }
    for (size_t i = 0; i < drop.size(); ++i) drop[i] += other.drop[i];
}

SegmentationStats::SegmentationStats() {
    for (size_t c = 0; c < 3; ++c)
        for (size_t v = 0; v < 256; ++v) lutOn[c][v] = lutOff[c][v] = std::uint8_t(v);
}

ChannelLut equalizationLut(const ChannelHistogram& histogram) {
    ChannelLut lut;
    std::uint64_t total = 0, cdfMin = 0;
    for (size_t v = 0; v < 256; ++v) {
        if (total == 0) cdfMin = histogram[v];
        total += histogram[v];
    }
    if (total == cdfMin) { // empty, or every pixel has the same value: nothing to spread
        for (size_t v = 0; v < 256; ++v) lut[v] = std::uint8_t(v);
        return lut;
    }
    std::uint64_t cdf = 0;
    for (size_t v = 0; v < 256; ++v) {
        cdf += histogram[v];
        const double t = cdf <= cdfMin ? 0.0 : double(cdf - cdfMin) / double(total - cdfMin);
        lut[v] = std::uint8_t(std::lround(255.0 * t));
    }
    return lut;
}

int otsuThreshold(const std::uint64_t* histogram, int bins) {
    double n = 0.0, sum = 0.0;
    for (int i = 0; i < bins; ++i) {
        n += double(histogram[i]);
        sum += double(i) * double(histogram[i]);
    }
    double w0 = 0.0, sum0 = 0.0, best = -1.0;
    int bestT = 0;
    for (int t = 0; t < bins - 1; ++t) {
        w0 += double(histogram[t]);
        sum0 += double(t) * double(histogram[t]);
        const double w1 = n - w0;
        if (w0 <= 0.0 || w1 <= 0.0) continue;
        const double m0 = sum0 / w0, m1 = (sum - sum0) / w1;
        const double between = w0 * w1 * (m0 - m1) * (m0 - m1);
        if (between > best) {
            best = between;
            bestT = t;
        }
    }
    return bestT;
}

int dropThresholdFromHistogram(const std::array<std::uint64_t, kSegDropBins>& drop) {
    // Pixels with dropBin > t are the upper class: dropBin >= t + 1, i.e. drop >= (t + 1 - bins/2) / scale.
    const int t = otsuThreshold(drop.data(), kSegDropBins) + 1 - kSegDropBins / 2;
    return t < kSegMinDrop ? kSegMinDrop : t;
}

SegmentationStats statsFromHistograms(const SegmentationHistograms& histograms, SegmentationMethod method) {
    SegmentationStats s;
    if (method == SegmentationMethod::Equalized)
        for (size_t c = 0; c < 3; ++c) {
            s.lutOn[c] = equalizationLut(histograms.on[c]);
            s.lutOff[c] = equalizationLut(histograms.off[c]);
        }
    if (method == SegmentationMethod::Default) s.dropThreshold = dropThresholdFromHistogram(histograms.drop);
    return s;
}

} // namespace seasonview
