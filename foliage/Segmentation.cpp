#include "Segmentation.h"

#include <opencv2/core.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <mutex>

// The per-texel loops are compiled twice, for AVX2 and for the baseline, and picked at load time (GCC function
// multi-versioning): on x86-64 the baseline has no 32-bit vector multiply and runs them 3-5x slower.
#if defined(__GNUC__) && defined(__x86_64__) && !defined(__clang__)
#define SEASONVIEW_VECTOR_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define SEASONVIEW_VECTOR_CLONES
#endif

namespace seasonview {

namespace {

// Output rows per parallel stripe: long enough that the halo recomputed per stripe does not show.
constexpr int kStripeRows = 64;

template <class Fn>
void forRows(int rows, const Fn& fn) {
    const int stripes = (rows + kStripeRows - 1) / kStripeRows;
    cv::parallel_for_(cv::Range(0, stripes), [&](const cv::Range& r) {
        for (int s = r.start; s < r.end; ++s) fn(s * kStripeRows, std::min(rows, (s + 1) * kStripeRows));
    });
}

// Reused buffers: a band is 10-100 MB of planes, and fresh allocations of that size cost more in page faults
// (the kernel zeroing pages) than the filters themselves. One set per thread; cv::Mat::create keeps a buffer of
// the same size and type.
struct Scratch {
    cv::Mat plane;                                                    // padded texel plane (calling thread)
    cv::Mat bits, sums;                                               // per stripe (worker threads)
    std::vector<std::uint16_t> rows3[3];                              // default's texture rings
    std::vector<std::int32_t> smooth, smoothSq, rows5[5], rows5Sq[5];
    std::vector<int> bins;
};
Scratch& scratch() {
    thread_local Scratch s;
    return s;
}

// ---- Per-texel kernels (n texels of interleaved RGB) ----

// §4.1 conditions packed for the vote: bit 0 leaf-on green, bit 8 leaf-off not green.
SEASONVIEW_VECTOR_CLONES
void paperTexels(const std::uint8_t* on, const std::uint8_t* off, int n, std::uint16_t* out) {
    for (int i = 0; i < n; ++i) {
        const std::uint8_t* a = on + 3 * i;
        const std::uint8_t* b = off + 3 * i;
        out[i] = std::uint16_t(int(greenIsMax(a[0], a[1], a[2])) + (greenIsMax(b[0], b[1], b[2]) ? 0 : 256));
    }
}

// The same through per-channel lookup tables (equalized): table lookups do not vectorise, so a loop of its own.
void paperTexelsLut(const std::uint8_t* on, const std::uint8_t* off, int n, const SegmentationStats& st,
                    std::uint16_t* out) {
    for (int i = 0; i < n; ++i) {
        const std::uint8_t* a = on + 3 * i;
        const std::uint8_t* b = off + 3 * i;
        const bool onGreen = greenIsMax(st.lutOn[0][a[0]], st.lutOn[1][a[1]], st.lutOn[2][a[2]]);
        const bool offGreen = greenIsMax(st.lutOff[0][b[0]], st.lutOff[1][b[1]], st.lutOff[2][b[2]]);
        out[i] = std::uint16_t(int(onGreen) + (offGreen ? 0 : 256));
    }
}

// default: bits 0..9 the leaf-on brightness r+g+b (<= 765), bit 15 the drop test.
SEASONVIEW_VECTOR_CLONES
void defaultTexels(const std::uint8_t* on, const std::uint8_t* off, int n, int t, std::uint16_t* out) {
    for (int i = 0; i < n; ++i) {
        const std::uint8_t* a = on + 3 * i;
        const std::uint8_t* b = off + 3 * i;
        const bool drop = dropAtLeast(a[0], a[1], a[2], b[0], b[1], b[2], t);
        out[i] = std::uint16_t((a[0] + a[1] + a[2]) | (drop ? 0x8000 : 0));
    }
}

// The texture stage of `default` as separable integer sums, streamed row by row through small ring buffers (they
// stay in cache; whole-plane box filters do not). Column j of each output is centred on input column j + the
// filter's half width.
static_assert(kSegTexturePrefilter == 3 && kSegTextureWindow == 5, "the texture kernels below are unrolled for 3, 5");

SEASONVIEW_VECTOR_CLONES
void rowSums3(const std::uint16_t* texel, int n, std::uint16_t* out) { // brightness (bits 0..14), n - 2 outputs
    for (int j = 0; j < n - 2; ++j)
        out[j] = std::uint16_t((texel[j] & 0x7FFF) + (texel[j + 1] & 0x7FFF) + (texel[j + 2] & 0x7FFF));
}

SEASONVIEW_VECTOR_CLONES
void columnSums3(const std::uint16_t* a, const std::uint16_t* b, const std::uint16_t* c, int n, std::int32_t* s,
                 std::int32_t* sq) {
    for (int j = 0; j < n; ++j) {
        const std::int32_t v = std::int32_t(a[j]) + b[j] + c[j];
        s[j] = v;
        sq[j] = v * v;
    }
}

SEASONVIEW_VECTOR_CLONES
void rowSums5(const std::int32_t* v, int n, std::int32_t* out) { // n - 4 outputs
    for (int j = 0; j < n - 4; ++j) out[j] = v[j] + v[j + 1] + v[j + 2] + v[j + 3] + v[j + 4];
}

// The per-texel decision the vote counts: the drop flag (bit 15 of `texel`) and the texture test on the 5×5 sums
// (five rows of row sums each).
SEASONVIEW_VECTOR_CLONES
void defaultBits(const std::uint16_t* __restrict texel, const std::int32_t* const* sum,
                 const std::int32_t* const* sumSq, int n, std::uint8_t* __restrict out) {
    constexpr double window = kSegTextureWindow * kSegTextureWindow;
    // Local restrict pointers: without them the stores to `out` might alias the row pointers and nothing vectorises.
    const std::int32_t *__restrict a0 = sum[0], *__restrict a1 = sum[1], *__restrict a2 = sum[2],
                       *__restrict a3 = sum[3], *__restrict a4 = sum[4];
    const std::int32_t *__restrict q0 = sumSq[0], *__restrict q1 = sumSq[1], *__restrict q2 = sumSq[2],
                       *__restrict q3 = sumSq[3], *__restrict q4 = sumSq[4];
    for (int j = 0; j < n; ++j) {
        const std::int32_t a = a0[j] + a1[j] + a2[j] + a3[j] + a4[j];
        const std::int32_t q = q0[j] + q1[j] + q2[j] + q3[j] + q4[j];
        out[j] = std::uint8_t(defaultTexel((texel[j] & 0x8000) != 0, textured(window, a, q)));
    }
}

SEASONVIEW_VECTOR_CLONES
void paperMajority(const std::uint16_t* sums, int n, int k, std::uint8_t* out) {
    for (int i = 0; i < n; ++i) out[i] = isMajority(sums[i] & 0xFF, k) && isMajority(sums[i] >> 8, k) ? 255 : 0;
}

SEASONVIEW_VECTOR_CLONES
void majority(const std::uint16_t* votes, int n, int k, std::uint8_t* out) {
    for (int i = 0; i < n; ++i) out[i] = isMajority(votes[i], k) ? 255 : 0;
}

// dropBin of n pixel pairs `step` pixels apart. The floor division in double is exact: numerator and denominator
// are integers below 2^28, so the quotient is exact when integral and otherwise at least 1/den from an integer.
SEASONVIEW_VECTOR_CLONES
void dropBins(const std::uint8_t* on, const std::uint8_t* off, int n, int step, int* out) {
    for (int i = 0; i < n; ++i) {
        const std::uint8_t* a = on + 3 * step * i;
        const std::uint8_t* b = off + 3 * step * i;
        const int dOn = exgDenominator(a[0], a[1], a[2]), dOff = exgDenominator(b[0], b[1], b[2]);
        const int num = exgNumerator(a[0], a[1], a[2]) * dOff - exgNumerator(b[0], b[1], b[2]) * dOn;
        const int q = int(std::floor(double(kSegDropScale * num) / double(dOn * dOff))) + kSegDropBins / 2;
        out[i] = q < 0 ? 0 : q >= kSegDropBins ? kSegDropBins - 1 : q;
    }
}

// ---- Planes ----

// The per-texel plane `kernel(on, off, n, out)` of every image row within `halo` of the output rows, padded by
// `halo` on every side: rows and columns outside the image repeat the edge (GL_CLAMP_TO_EDGE). Padded row i,
// column j is image row clamp(outRow0 - halo + i), column clamp(j - halo). Lives in the calling thread's scratch.
template <class Kernel>
const cv::Mat& texelPlane(const RgbRows& in, int outRow0, int outRows, int halo, const Kernel& kernel) {
    const int first = std::max(0, outRow0 - halo), last = std::min(in.imageHeight, outRow0 + outRows + halo);
    assert(first >= in.row0 && last <= in.row0 + in.rows && "segmentRows(): the input rows do not cover the halo");
    const int w = in.width, top = first - (outRow0 - halo), bottom = top + (last - first);
    cv::Mat& plane = scratch().plane;
    plane.create(outRows + 2 * halo, w + 2 * halo, CV_16U);
    forRows(last - first, [&](int r0, int r1) {
        for (int r = r0; r < r1; ++r) {
            const size_t base = size_t(first + r - in.row0) * size_t(w) * 3;
            std::uint16_t* o = plane.ptr<std::uint16_t>(top + r);
            kernel(in.on + base, in.off + base, w, o + halo);
            std::fill(o, o + halo, o[halo]);
            std::fill(o + halo + w, o + 2 * halo + w, o[halo + w - 1]);
        }
    });
    for (int i = 0; i < top; ++i) plane.row(top).copyTo(plane.row(i));
    for (int i = bottom; i < plane.rows; ++i) plane.row(bottom - 1).copyTo(plane.row(i));
    return plane;
}

constexpr int kIsolated = cv::BORDER_REPLICATE | cv::BORDER_ISOLATED;

// Unnormalised k×k box sums of `src` (whose rows and columns at least k/2 inside the edge are the valid ones)
// into `sums`; a filter on an isolated ROI, so each stripe is independent of its neighbours.
void boxSums(const cv::Mat& src, int k, int ddepth, cv::Mat& sums) {
    if (k == 1) src.convertTo(sums, ddepth);
    else cv::boxFilter(src, sums, ddepth, cv::Size(k, k), cv::Point(-1, -1), false, kIsolated);
}

// pixel / neighborhood / equalized: the two §4.1 conditions per texel packed as on + 256 off; one k×k box sum holds
// both vote counts (k <= 15: at most 225 each, no carry into the other byte).
void segmentPaper(const RgbRows& in, int outRow0, int outRows, int k, bool lut, const SegmentationStats& st,
                  std::uint8_t* mask) {
    const int h = k / 2, w = in.width;
    const cv::Mat& plane =
        texelPlane(in, outRow0, outRows, h, [&](const std::uint8_t* a, const std::uint8_t* b, int n, std::uint16_t* o) {
            if (lut) paperTexelsLut(a, b, n, st, o);
            else paperTexels(a, b, n, o);
        });
    forRows(outRows, [&](int r0, int r1) {
        cv::Mat& sums = scratch().sums;
        boxSums(plane.rowRange(r0, r1 + 2 * h), k, CV_16U, sums);
        for (int r = r0; r < r1; ++r)
            paperMajority(sums.ptr<std::uint16_t>(r - r0 + h) + h, w, k, mask + size_t(r) * size_t(w));
    });
}

// default: the drop test per texel, the texture test on the 3×3-smoothed brightness over 5×5, then a k×k vote of
// their conjunction. Integer sums throughout (3×3 sums <= 6885, their squares < 2^26, 5×5 sums < 2^31): exact.
void segmentDefault(const RgbRows& in, int outRow0, int outRows, int k, const SegmentationStats& st,
                    std::uint8_t* mask) {
    const int h = k / 2, e = kSegTextureHalo, halo = h + e, t = st.dropThreshold, w = in.width;
    const cv::Mat& plane =
        texelPlane(in, outRow0, outRows, halo, [t](const std::uint8_t* a, const std::uint8_t* b, int n,
                                                   std::uint16_t* o) { defaultTexels(a, b, n, t, o); });
    forRows(outRows, [&](int r0, int r1) {
        // Stripe rows [r0, r1) need padded rows [r0, r1 + 2 halo); `bits` holds rows and columns e.. of them.
        const cv::Mat src = plane.rowRange(r0, r1 + 2 * halo);
        const int cols = src.cols;
        Scratch& sc = scratch();
        for (auto& v : sc.rows3) v.resize(size_t(cols));
        for (int i = 0; i < 5; ++i) {
            sc.rows5[i].resize(size_t(cols));
            sc.rows5Sq[i].resize(size_t(cols));
        }
        sc.smooth.resize(size_t(cols));
        sc.smoothSq.resize(size_t(cols));
        sc.bits.create(src.rows - 2 * e, cols - 2 * e, CV_8U);
        for (int r = 0; r < src.rows; ++r) {
            rowSums3(src.ptr<std::uint16_t>(r), cols, sc.rows3[r % 3].data());
            const int m = r - 1; // the 3×3 sums of row m are complete
            if (m < 1) continue;
            columnSums3(sc.rows3[(m - 1) % 3].data(), sc.rows3[m % 3].data(), sc.rows3[(m + 1) % 3].data(), cols - 2,
                        sc.smooth.data(), sc.smoothSq.data());
            rowSums5(sc.smooth.data(), cols - 2, sc.rows5[m % 5].data());
            rowSums5(sc.smoothSq.data(), cols - 2, sc.rows5Sq[m % 5].data());
            const int o = m - 2; // the 5×5 window centred on row o spans rows o - 2 .. m
            if (o < e) continue;
            const std::int32_t* sum[5];
            const std::int32_t* sumSq[5];
            for (int i = 0; i < 5; ++i) {
                sum[i] = sc.rows5[(o - 2 + i) % 5].data();
                sumSq[i] = sc.rows5Sq[(o - 2 + i) % 5].data();
            }
            defaultBits(src.ptr<std::uint16_t>(o) + e, sum, sumSq, cols - 2 * e, sc.bits.ptr<std::uint8_t>(o - e));
        }
        // The vote: output row r of the stripe is row r - r0 + h of `bits`, column x is x + h.
        boxSums(sc.bits, k, CV_16U, sc.sums);
        for (int r = r0; r < r1; ++r)
            majority(sc.sums.ptr<std::uint16_t>(r - r0 + h) + h, w, k, mask + size_t(r) * size_t(w));
    });
}

} // namespace

int effectiveK(const SegmentationParams& params) {
    return params.method == SegmentationMethod::Pixel ? 1 : params.k;
}

int segmentationHalo(const SegmentationParams& params) {
    const int h = effectiveK(params) / 2;
    return params.method == SegmentationMethod::Default ? h + kSegTextureHalo : h;
}

void segmentRows(const RgbRows& in, int outRow0, int outRows, const SegmentationParams& params,
                 const SegmentationStats& stats, std::uint8_t* mask) {
    const int k = effectiveK(params);
    assert(k >= 1 && k <= kSegMaxK && k % 2 == 1 && "segmentRows(): k must be odd, 1..kSegMaxK");
    assert(outRow0 >= 0 && outRows >= 0 && outRow0 + outRows <= in.imageHeight && "segmentRows(): rows outside");
    if (outRows == 0 || in.width == 0) return;
    if (params.method == SegmentationMethod::Default) segmentDefault(in, outRow0, outRows, k, stats, mask);
    else segmentPaper(in, outRow0, outRows, k, params.method == SegmentationMethod::Equalized, stats, mask);
}

bool splitPairRgba(const std::uint8_t* onRgba, const std::uint8_t* offRgba, size_t n, std::uint8_t* onRgb,
                   std::uint8_t* offRgb, std::uint8_t* valid) {
    bool all = true;
    for (size_t i = 0; i < n; ++i) {
        for (size_t c = 0; c < 3; ++c) {
            onRgb[3 * i + c] = onRgba[4 * i + c];
            offRgb[3 * i + c] = offRgba[4 * i + c];
        }
        const bool v = onRgba[4 * i + 3] != 0 && offRgba[4 * i + 3] != 0;
        valid[i] = v ? 255 : 0;
        all &= v;
    }
    return all;
}

SegmentationHistograms rowHistograms(const RgbRows& in, bool colour, bool drop) {
    SegmentationHistograms total;
    std::mutex m;
    const size_t rowBytes = size_t(in.width) * 3;
    const int step = kSegHistogramStep, sampled = (in.width + step - 1) / step;
    forRows(in.rows, [&](int r0, int r1) {
        SegmentationHistograms part;
        std::vector<int>& bins = scratch().bins;
        bins.resize(size_t(sampled));
        for (int r = r0; r < r1; ++r) {
            if ((in.row0 + r) % step != 0) continue; // sampled rows are fixed in image rows: bands agree
            const std::uint8_t* a = in.on + size_t(r) * rowBytes;
            const std::uint8_t* b = in.off + size_t(r) * rowBytes;
            const std::uint8_t* valid = in.valid ? in.valid + size_t(r) * size_t(in.width) : nullptr;
            if (colour)
                for (int x = 0; x < in.width; x += step) {
                    if (valid && !valid[x]) continue;
                    for (size_t c = 0; c < 3; ++c) {
                        ++part.on[c][a[3 * size_t(x) + c]];
                        ++part.off[c][b[3 * size_t(x) + c]];
                    }
                }
            if (drop) {
                dropBins(a, b, sampled, step, bins.data());
                for (int i = 0; i < sampled; ++i)
                    if (!valid || valid[size_t(i) * size_t(step)]) ++part.drop[size_t(bins[size_t(i)])];
            }
        }
        std::lock_guard<std::mutex> lock(m);
        total.merge(part);
    });
    return total;
}

SegmentationHistograms pairHistograms(const Image<std::uint8_t>& on, const Image<std::uint8_t>& off, bool colour,
                                      bool drop) {
    assert(on.width == off.width && on.height == off.height && on.channels == 3 && off.channels == 3 &&
           "pairHistograms(): two RGB images of the same size");
    return rowHistograms(RgbRows{on.pixels.data(), off.pixels.data(), on.width, on.height, 0, on.height}, colour, drop);
}

Image<std::uint8_t> segmentImage(const Image<std::uint8_t>& on, const Image<std::uint8_t>& off,
                                 const SegmentationParams& params) {
    assert(on.width == off.width && on.height == off.height && on.channels == 3 && off.channels == 3 &&
           "segmentImage(): two RGB images of the same size");
    const bool colour = params.method == SegmentationMethod::Equalized;
    const bool drop = params.method == SegmentationMethod::Default;
    const SegmentationStats stats = needsHistograms(params.method)
                                        ? statsFromHistograms(pairHistograms(on, off, colour, drop), params.method)
                                        : SegmentationStats{};
    Image<std::uint8_t> mask;
    mask.width = on.width;
    mask.height = on.height;
    mask.channels = 1;
    mask.pixels.assign(size_t(on.width) * size_t(on.height), 0);
    const RgbRows in{on.pixels.data(), off.pixels.data(), on.width, on.height, 0, on.height};
    segmentRows(in, 0, on.height, params, stats, mask.pixels.data());
    return mask;
}

} // namespace seasonview
