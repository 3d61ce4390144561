#include "CrownCentres.h"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cassert>
#include <cmath>

namespace seasonview {

namespace {

constexpr double kMinCrownRadiusM = 1.0, kMaxCrownRadiusM = 15.0;

// A crown's radius from the distance of its centre pixel to the nearest background pixel centre: the edge lies half
// a pixel before that centre.
double crownRadius(float dist) { return std::max(0.5, double(dist) - 0.5); }

int windowRadius(const CrownParams& p, float dist) {
    return std::max(1, int(std::ceil(p.separation * double(dist))));
}

// Whether the clamped distance at (x, y) is a crown centre: at least minRadius, and within its window no larger
// value and no equal value earlier in raster order (one centre per plateau).
bool isCentre(const cv::Mat& dist, int x, int y, const CrownParams& p) {
    const float v = dist.at<float>(y, x);
    if (crownRadius(v) < p.minRadiusPx) return false;
    // Cheap 3×3 test first: almost every pixel fails it.
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
            const int xx = x + dx, yy = y + dy;
            if ((dx || dy) && xx >= 0 && yy >= 0 && xx < dist.cols && yy < dist.rows) {
                const float q = dist.at<float>(yy, xx);
                if (q > v || (q == v && (dy < 0 || (dy == 0 && dx < 0)))) return false;
            }
        }
    const int s = windowRadius(p, v);
    for (int yy = std::max(0, y - s); yy <= std::min(dist.rows - 1, y + s); ++yy) {
        const float* row = dist.ptr<float>(yy);
        for (int xx = std::max(0, x - s); xx <= std::min(dist.cols - 1, x + s); ++xx) {
            const float q = row[xx];
            if (q > v || (q == v && (yy < y || (yy == y && xx < x)))) return false;
        }
    }
    return true;
}

} // namespace

CrownParams crownParamsForGsd(double gsd) {
    assert(gsd > 0.0 && "crownParamsForGsd(): gsd must be positive");
    CrownParams p;
    p.minRadiusPx = std::max(1.0, kMinCrownRadiusM / gsd);
    p.maxRadiusPx = std::max(2, int(std::ceil(kMaxCrownRadiusM / gsd)));
    return p;
}

int crownHalo(const CrownParams& params) {
    return params.maxRadiusPx + windowRadius(params, float(params.maxRadiusPx)) + 1;
}

void detectCrownRows(const std::uint8_t* mask, int width, int imageHeight, int row0, int rows, int outRow0,
                     int outRows, const CrownParams& params, std::vector<CrownDetection>& out) {
    if (outRows <= 0 || width <= 0) return;
    const int halo = crownHalo(params);
    const int first = std::max(0, outRow0 - halo), last = std::min(imageHeight, outRow0 + outRows + halo);
    assert(first >= row0 && last <= row0 + rows && "detectCrownRows(): the mask rows do not cover the halo");
    (void)rows;
    const cv::Mat src(last - first, width, CV_8U,
                      const_cast<std::uint8_t*>(mask + size_t(first - row0) * size_t(width)));
    cv::Mat dist;
    cv::distanceTransform(src, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);
    cv::min(dist, float(params.maxRadiusPx), dist);
    for (int y = outRow0 - first; y < outRow0 - first + outRows; ++y) {
        const float* d = dist.ptr<float>(y);
        for (int x = 0; x < width; ++x)
            if (crownRadius(d[x]) >= params.minRadiusPx && isCentre(dist, x, y, params))
                out.push_back({x + 0.5, first + y + 0.5, crownRadius(d[x])});
    }
}

std::vector<CrownDetection> detectCrowns(const Image<std::uint8_t>& mask, const CrownParams& params) {
    assert(mask.channels == 1 && "detectCrowns(): a one-channel mask");
    std::vector<CrownDetection> out;
    detectCrownRows(mask.pixels.data(), mask.width, mask.height, 0, mask.height, 0, mask.height, params, out);
    return out;
}

} // namespace seasonview
