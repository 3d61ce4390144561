#include "DepthAccuracy.h"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace seasonview {

DepthAccuracy compareDepth(const std::vector<float>& reference, const std::vector<float>& test, int width, int height,
                           double near) {
    assert(reference.size() == size_t(width) * size_t(height) && test.size() == reference.size() &&
           "compareDepth(): buffer sizes differ");
    auto eye = [&](const std::vector<float>& d, int x, int y) {
        const float v = d[size_t(y) * size_t(width) + size_t(x)];
        return v > 0.0f ? near / double(v) : -1.0;
    };
    DepthAccuracy a;
    std::vector<double> errors;
    double sumDepth = 0;
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const double r = eye(reference, x, y), t = eye(test, x, y);
            if ((r < 0) != (t < 0)) ++a.onlyOne;
            if (r < 0 || t < 0) continue;
            // Central differences of the reference's eye depth, one-sided at edges and next to sky.
            auto slope = [&](int dx, int dy) {
                const int x0 = std::max(x - dx, 0), y0 = std::max(y - dy, 0);
                const int x1 = std::min(x + dx, width - 1), y1 = std::min(y + dy, height - 1);
                double a0 = eye(reference, x0, y0), a1 = eye(reference, x1, y1);
                int span = (x1 - x0) + (y1 - y0);
                if (a0 < 0) { a0 = r; span -= dx + dy; }
                if (a1 < 0) { a1 = r; span -= dx + dy; }
                return span > 0 ? (a1 - a0) / span : 0.0;
            };
            const double g = std::hypot(slope(1, 0), slope(0, 1));
            const double dz = std::abs(t - r);
            sumDepth += dz;
            errors.push_back(g > 1e-9 ? dz / g : (dz > 1e-6 ? 1e9 : 0.0));
        }
    a.pixels = std::int64_t(errors.size());
    if (errors.empty()) return a;
    double sum = 0;
    for (double e : errors) sum += std::min(e, 1e3); // a pixel counts at most 1000 px (isolated flat-gradient noise)
    a.meanErrorPx = sum / double(errors.size());
    a.meanAbsDepthM = sumDepth / double(errors.size());
    const size_t k = size_t(0.95 * double(errors.size() - 1));
    std::nth_element(errors.begin(), errors.begin() + std::ptrdiff_t(k), errors.end());
    a.p95ErrorPx = errors[k];
    return a;
}

} // namespace seasonview
