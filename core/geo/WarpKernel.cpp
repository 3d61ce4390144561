#include "WarpKernel.h"

#include "ParallelIndices.h"

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

namespace seasonview {

namespace {

bool finite(glm::dvec2 p) { return std::isfinite(p.x) && std::isfinite(p.y); }

} // namespace

SourceLattice SourceLattice::build(int x0, int y0, int x1, int y1,
                                   const std::function<void(std::span<glm::dvec2>)>& map, double maxError) {
    SourceLattice l;
    l.m_x0 = x0;
    l.m_y0 = y0;
    for (int step = 32;; step /= 2) {
        l.m_step = step;
        l.m_cols = std::max(1, (x1 - x0 + step - 1) / step);
        l.m_rows = std::max(1, (y1 - y0 + step - 1) / step);
        l.m_points.resize(size_t(l.m_cols + 1) * size_t(l.m_rows + 1));
        for (int j = 0; j <= l.m_rows; ++j)
            for (int i = 0; i <= l.m_cols; ++i)
                l.m_points[size_t(j) * size_t(l.m_cols + 1) + size_t(i)] =
                    glm::dvec2(x0 + i * step + 0.5, y0 + j * step + 0.5);
        map(std::span<glm::dvec2>(l.m_points));
        if (step <= 2) break;
        // The interpolation error at the centres of (up to 64) cells spread over the lattice.
        std::vector<glm::dvec2> probe, expected;
        const int every = std::max(1, (l.m_cols * l.m_rows) / 64);
        for (int c = 0; c < l.m_cols * l.m_rows; c += every) {
            const int i = c % l.m_cols, j = c / l.m_cols;
            probe.push_back(glm::dvec2(x0 + i * step + step / 2 + 0.5, y0 + j * step + step / 2 + 0.5));
            expected.push_back(l.at(x0 + i * step + step / 2, y0 + j * step + step / 2));
        }
        map(std::span<glm::dvec2>(probe));
        double worst = 0.0;
        bool nonFinite = false;
        for (size_t k = 0; k < probe.size(); ++k) {
            if (!finite(probe[k]) || !finite(expected[k])) {
                nonFinite = true;
                continue;
            }
            worst = std::max(worst, glm::length(probe[k] - expected[k]));
        }
        if (worst <= maxError && !nonFinite) break;
    }
    l.m_min = glm::dvec2(std::numeric_limits<double>::max());
    l.m_max = glm::dvec2(std::numeric_limits<double>::lowest());
    for (const glm::dvec2& p : l.m_points)
        if (finite(p)) {
            l.m_min = glm::min(l.m_min, p);
            l.m_max = glm::max(l.m_max, p);
        }
    return l;
}

glm::dvec2 SourceLattice::at(int x, int y) const {
    const double fx = double(x - m_x0) / m_step, fy = double(y - m_y0) / m_step;
    const int i = std::clamp(int(fx), 0, m_cols - 1), j = std::clamp(int(fy), 0, m_rows - 1);
    const double tx = fx - i, ty = fy - j;
    const size_t w = size_t(m_cols + 1);
    const glm::dvec2 a = m_points[size_t(j) * w + size_t(i)], b = m_points[size_t(j) * w + size_t(i) + 1];
    const glm::dvec2 c = m_points[size_t(j + 1) * w + size_t(i)], d = m_points[size_t(j + 1) * w + size_t(i) + 1];
    return (a * (1.0 - tx) + b * tx) * (1.0 - ty) + (c * (1.0 - tx) + d * tx) * ty;
}

template <typename T>
void resampleWindow(const SourceLattice& lattice, const SourceWindow<T>& src, bool bilinear, int x0, int y0, int x1,
                    int y1, T* out, std::uint8_t* coverage, int outWidth, int outRow0, int outCol0, int threads) {
    const int n = src.channels;
    const int rows = y1 - y0;
    parallelIndices((rows + 15) / 16, threads, [&](int chunk, int) {
        for (int y = y0 + chunk * 16; y < std::min(y1, y0 + chunk * 16 + 16); ++y) {
            const size_t row = size_t(y - outRow0) * size_t(outWidth);
            // The source position walks linearly across each lattice cell: evaluated at its columns and stepped.
            for (int x = x0; x < x1; ++x) {
                const glm::dvec2 s = lattice.at(x, y) - glm::dvec2(src.x0, src.y0);
                if (!finite(s)) continue;
                T* o = out + (row + size_t(x - outCol0)) * size_t(n);
                if (!bilinear) {
                    const int sx = int(std::floor(s.x)), sy = int(std::floor(s.y));
                    if (sx < 0 || sy < 0 || sx >= src.width || sy >= src.height) continue;
                    const size_t i = size_t(sy) * size_t(src.width) + size_t(sx);
                    if (!src.valid[i]) continue;
                    for (int c = 0; c < n; ++c) o[c] = src.samples[i * size_t(n) + size_t(c)];
                    coverage[row + size_t(x - outCol0)] = 255;
                    continue;
                }
                const double px = s.x - 0.5, py = s.y - 0.5; // pixel centres
                const int ix = int(std::floor(px)), iy = int(std::floor(py));
                const double tx = px - ix, ty = py - iy;
                double acc[8] = {0, 0, 0, 0, 0, 0, 0, 0};
                double weight = 0.0;
                for (int dy = 0; dy < 2; ++dy) {
                    const int yy = iy + dy;
                    if (yy < 0 || yy >= src.height) continue;
                    const double wy = dy ? ty : 1.0 - ty;
                    for (int dx = 0; dx < 2; ++dx) {
                        const int xx = ix + dx;
                        if (xx < 0 || xx >= src.width) continue;
                        const size_t i = size_t(yy) * size_t(src.width) + size_t(xx);
                        if (!src.valid[i]) continue;
                        const double w = wy * (dx ? tx : 1.0 - tx);
                        if (w == 0.0) continue;
                        weight += w;
                        for (int c = 0; c < n; ++c) acc[c] += w * double(src.samples[i * size_t(n) + size_t(c)]);
                    }
                }
                if (weight < 0.5) continue; // less than half the footprint has data
                for (int c = 0; c < n; ++c) {
                    const double v = acc[c] / weight;
                    if constexpr (std::is_floating_point_v<T>) o[c] = T(v);
                    else o[c] = T(std::clamp(v + 0.5, 0.0, double(std::numeric_limits<T>::max())));
                }
                coverage[row + size_t(x - outCol0)] = 255;
            }
        }
    });
}

template void resampleWindow<std::uint8_t>(const SourceLattice&, const SourceWindow<std::uint8_t>&, bool, int, int, int,
                                           int, std::uint8_t*, std::uint8_t*, int, int, int, int);
template void resampleWindow<std::uint16_t>(const SourceLattice&, const SourceWindow<std::uint16_t>&, bool, int, int,
                                            int, int, std::uint16_t*, std::uint8_t*, int, int, int, int);
template void resampleWindow<float>(const SourceLattice&, const SourceWindow<float>&, bool, int, int, int, int, float*,
                                    std::uint8_t*, int, int, int, int);

} // namespace seasonview
