#include "SegmentationMetrics.h"

#include <algorithm>
#include <cmath>
#include <tuple>

namespace seasonview {

void Confusion::add(const std::uint8_t* mask, const std::uint8_t* truth, std::size_t n, const std::uint8_t* scored) {
    std::uint64_t a = 0, b = 0, both = 0, left = 0;
    for (std::size_t i = 0; i < n; ++i) {
        if (scored && !scored[i]) {
            ++left;
            continue;
        }
        const bool m = mask[i] != 0, t = truth[i] != 0;
        a += m;
        b += t;
        both += m && t;
    }
    tp += both;
    fp += a - both;
    fn += b - both;
    tn += n - left - a - b + both;
    excluded += left;
}

Confusion& Confusion::operator+=(const Confusion& o) {
    tp += o.tp;
    fp += o.fp;
    fn += o.fn;
    tn += o.tn;
    excluded += o.excluded;
    return *this;
}

namespace {
double ratio(std::uint64_t num, std::uint64_t den) { return den == 0 ? 0.0 : double(num) / double(den); }
} // namespace

double Confusion::precision() const { return ratio(tp, tp + fp); }
double Confusion::recall() const { return ratio(tp, tp + fn); }
double Confusion::f1() const { return ratio(2 * tp, 2 * tp + fp + fn); }
double Confusion::iou() const { return ratio(tp, tp + fp + fn); }

CentreScores matchCentres(const std::vector<CrownPoint>& detected, const std::vector<CrownPoint>& truth) {
    CentreScores s;
    s.detected = int(detected.size());
    s.truth = int(truth.size());
    // Candidate pairs through a grid of the true trees (cell = largest true radius), then closest first.
    double maxR = 0.0;
    for (const CrownPoint& t : truth) maxR = std::max(maxR, t.radiusM);
    if (truth.empty() || detected.empty() || maxR <= 0.0) return s;
    auto cell = [&](double v) { return std::int64_t(std::floor(v / maxR)); };
    std::vector<std::tuple<std::int64_t, std::int64_t, int>> grid; // (cx, cy, truth index), sorted
    grid.reserve(truth.size());
    for (size_t i = 0; i < truth.size(); ++i) grid.emplace_back(cell(truth[i].x), cell(truth[i].y), int(i));
    std::sort(grid.begin(), grid.end());
    std::vector<std::tuple<double, int, int>> pairs; // (distance, detection, truth)
    for (size_t d = 0; d < detected.size(); ++d) {
        const std::int64_t cx = cell(detected[d].x), cy = cell(detected[d].y);
        for (std::int64_t gx = cx - 1; gx <= cx + 1; ++gx)
            for (std::int64_t gy = cy - 1; gy <= cy + 1; ++gy) {
                auto it = std::lower_bound(grid.begin(), grid.end(), std::make_tuple(gx, gy, -1));
                for (; it != grid.end() && std::get<0>(*it) == gx && std::get<1>(*it) == gy; ++it) {
                    const CrownPoint& t = truth[size_t(std::get<2>(*it))];
                    const double dist = std::hypot(detected[d].x - t.x, detected[d].y - t.y);
                    if (dist <= t.radiusM) pairs.emplace_back(dist, int(d), std::get<2>(*it));
                }
            }
    }
    std::sort(pairs.begin(), pairs.end());
    std::vector<char> usedD(detected.size(), 0), usedT(truth.size(), 0);
    for (const auto& [dist, d, t] : pairs) {
        if (usedD[size_t(d)] || usedT[size_t(t)]) continue;
        usedD[size_t(d)] = usedT[size_t(t)] = 1;
        ++s.matched;
    }
    return s;
}

} // namespace seasonview
