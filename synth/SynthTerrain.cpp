#include "SynthTerrain.h"

#include "SynthLayout.h"
#include "SynthParallel.h"
#include "SynthRandom.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

namespace seasonview::synth {

void Terrain::rowsRead(float fy, int& first, int& last) const {
    fy = std::clamp(fy, 0.0f, float(height - 1));
    first = std::min(int(fy), height - 2 < 0 ? 0 : height - 2);
    last = std::min(first + 1, height - 1);
}

Terrain makeFbmTerrain(int samples, float spacing, const Layout& layout, std::uint64_t seed, int threads) {
    Terrain t;
    t.width = t.height = samples;
    t.spacing = spacing;
    t.halfExtent = 0.5f * float(samples) * spacing;
    t.z.resize(size_t(samples) * size_t(samples));
    const auto s = static_cast<std::uint32_t>(mixSeed(seed, 41));
    const float base = 80.0f + 25.0f * unitFloat(s);
    const River& rv = layout.river;
    parallelChunks(samples, 16, threads, [&](int j0, int j1) {
        for (int j = j0; j < j1; ++j)
            for (int i = 0; i < samples; ++i) {
                const glm::vec2 p(-t.halfExtent + (float(i) + 0.5f) * spacing, t.halfExtent - (float(j) + 0.5f) * spacing);
                // Rolling hills (~±55 m over 1.5 km, ±8 m over 400 m) with small undulations, so oblique views show
                // relief; a broad valley along the river with a steeper drop at the banks.
                float z = base + 55.0f * fbm(p.x / 1500.0f, p.y / 1500.0f, s + 1, 4) +
                          8.0f * fbm(p.x / 400.0f, p.y / 400.0f, s + 4, 3) +
                          2.5f * fbm(p.x / 220.0f, p.y / 220.0f, s + 2, 3) + 0.25f * valueNoise(p.x / 12.0f, p.y / 12.0f, s + 3);
                const float rd = rv.distance(layout.warp.toLayout(p), rv.halfWidth + 241.0f);
                z -= 18.0f * smoothstep(rv.halfWidth + 240.0f, rv.halfWidth + 5.0f, rd);
                z -= 1.8f * smoothstep(rv.halfWidth + rv.bankWidth + 2.0f, rv.halfWidth, rd);
                t.z[size_t(j) * size_t(samples) + size_t(i)] = z;
            }
    });
    return t;
}

Result<DemSource> openDem(const std::filesystem::path& path) {
    auto info = readRasterInfo(path);
    if (!info) return info.error();
    if (!info->georef) return fileError(path.string(), "DEM has no georeferencing (GeoTIFF tags)");
    auto image = readImageF32(path, 1);
    if (!image) return image.error();
    DemSource d;
    d.path = path;
    d.info = *info;
    d.image = std::move(*image);
    const Georef& g = *d.info.georef;
    const glm::dvec2 c = g.pixelToCrs(glm::dvec2(0.5 * double(d.image.width), 0.5 * double(d.image.height)));
    d.centreLonLat = g.crs.isGeographic() ? c : convert(g.crs, Crs::geographic(), c);
    return d;
}

namespace {

bool validHeight(float v, const std::optional<double>& nodata) {
    if (!std::isfinite(v) || v < -1000.0f || v > 9000.0f) return false; // SRTM voids are -32768
    return !nodata || double(v) != *nodata;
}

// Bilinear over the valid corners of a DEM cell at fractional sample coordinates; NaN outside or all invalid.
float demBilinear(const Image<float>& img, const std::optional<double>& nodata, double fx, double fy) {
    if (fx < -0.5 || fy < -0.5 || fx > double(img.width) - 0.5 || fy > double(img.height) - 0.5)
        return std::numeric_limits<float>::quiet_NaN();
    fx = std::clamp(fx, 0.0, double(img.width - 1));
    fy = std::clamp(fy, 0.0, double(img.height - 1));
    const int i = int(fx), j = int(fy);
    const int i1 = std::min(i + 1, img.width - 1), j1 = std::min(j + 1, img.height - 1);
    const double tx = fx - i, ty = fy - j;
    const int xs[4] = {i, i1, i, i1}, ys[4] = {j, j, j1, j1};
    const double ws[4] = {(1 - tx) * (1 - ty), tx * (1 - ty), (1 - tx) * ty, tx * ty};
    double sum = 0.0, wsum = 0.0;
    for (int k = 0; k < 4; ++k) {
        const float v = img.at(xs[k], ys[k]);
        if (ws[k] > 0.0 && validHeight(v, nodata)) {
            sum += ws[k] * double(v);
            wsum += ws[k];
        }
    }
    return wsum > 1e-9 ? static_cast<float>(sum / wsum) : std::numeric_limits<float>::quiet_NaN();
}

} // namespace

Result<Terrain> resampleDem(const DemSource& dem, int samples, float spacing, const Crs& sceneCrs, glm::dvec2 centre,
                            int threads) {
    Terrain t;
    t.width = t.height = samples;
    t.spacing = spacing;
    t.halfExtent = 0.5f * float(samples) * spacing;
    const size_t n = size_t(samples);
    t.z.assign(n * n, std::numeric_limits<float>::quiet_NaN());
    const Georef& g = *dem.info.georef;

    // UTM -> DEM pixel on a coarse lattice (every 16 samples), bilinear in between: the mapping is smooth to far
    // below a millimetre over that distance and this saves millions of projections.
    const int step = 16, nl = (samples + step - 1) / step + 1;
    std::vector<glm::dvec2> lattice(size_t(nl) * size_t(nl));
    for (int b = 0; b < nl; ++b)
        for (int a = 0; a < nl; ++a) {
            const glm::dvec2 local(-double(t.halfExtent) + (double(a * step) + 0.5) * spacing,
                                   double(t.halfExtent) - (double(b * step) + 0.5) * spacing);
            const glm::dvec2 p = convert(sceneCrs, g.crs, centre + local);
            lattice[size_t(b) * size_t(nl) + size_t(a)] = g.crsToPixel(p) - glm::dvec2(0.5);
        }
    parallelChunks(samples, 16, threads, [&](int j0, int j1) {
        for (int j = j0; j < j1; ++j)
            for (int i = 0; i < samples; ++i) {
                const int a = i / step, b = j / step;
                const double tx = double(i % step) / step, ty = double(j % step) / step;
                const glm::dvec2* r0 = &lattice[size_t(b) * size_t(nl) + size_t(a)];
                const glm::dvec2* r1 = r0 + nl;
                const glm::dvec2 px = (r0[0] * (1 - tx) + r0[1] * tx) * (1 - ty) + (r1[0] * (1 - tx) + r1[1] * tx) * ty;
                t.z[size_t(j) * n + size_t(i)] = demBilinear(dem.image, dem.info.nodata, px.x, px.y);
            }
    });

    // Shade from a version smoothed over about half the source spacing.
    const double srcSpacing = g.crs.isGeographic() ? g.pixelSize.y * 111320.0 : g.pixelSize.y;
    t.shadeBlur = std::clamp(static_cast<int>(0.5 * srcSpacing / spacing), 0, 64);

    // Fill holes ring by ring from the valid samples inwards: each hole gets the mean of its 4-neighbours filled
    // in earlier rings (deterministic, linear time).
    size_t holes = 0;
    for (float v : t.z) holes += std::isnan(v) ? 1 : 0;
    if (holes == n * n)
        return fileError(dem.path.string(), "no valid elevation sample within the scene's extent around the DEM's centre");
    std::vector<std::uint8_t> queued(n * n, 0);
    std::vector<size_t> ring, next;
    auto neighbours = [&](size_t k, auto&& fn) {
        const size_t i = k % n, j = k / n;
        if (i > 0) fn(k - 1);
        if (i + 1 < n) fn(k + 1);
        if (j > 0) fn(k - n);
        if (j + 1 < n) fn(k + n);
    };
    for (size_t k = 0; k < n * n; ++k)
        if (std::isnan(t.z[k]))
            neighbours(k, [&](size_t m) {
                if (!queued[k] && !std::isnan(t.z[m])) {
                    queued[k] = 1;
                    ring.push_back(k);
                }
            });
    std::vector<float> values;
    while (!ring.empty()) {
        values.clear();
        for (size_t k : ring) {
            double sum = 0.0;
            int cnt = 0;
            neighbours(k, [&](size_t m) {
                if (!std::isnan(t.z[m])) {
                    sum += t.z[m];
                    ++cnt;
                }
            });
            values.push_back(static_cast<float>(sum / cnt));
        }
        next.clear();
        for (size_t r = 0; r < ring.size(); ++r) t.z[ring[r]] = values[r];
        for (size_t k : ring)
            neighbours(k, [&](size_t m) {
                if (!queued[m] && std::isnan(t.z[m])) {
                    queued[m] = 1;
                    next.push_back(m);
                }
            });
        ring.swap(next);
    }
    return t;
}

namespace {

// Two passes of a separable box blur of radius r (clamped at the borders): close to a Gaussian, O(n).
std::vector<float> smoothed(const std::vector<float>& z, int w, int h, int r, int threads) {
    std::vector<float> a = z, b(z.size());
    auto pass = [&](const std::vector<float>& src, std::vector<float>& dst, bool horizontal) {
        const int lines = horizontal ? h : w, len = horizontal ? w : h;
        parallelChunks(lines, 16, threads, [&](int l0, int l1) {
            for (int l = l0; l < l1; ++l) {
                auto at = [&](int k) {
                    k = std::clamp(k, 0, len - 1);
                    return double(src[horizontal ? size_t(l) * size_t(w) + size_t(k) : size_t(k) * size_t(w) + size_t(l)]);
                };
                double sum = 0.0;
                for (int k = -r; k <= r; ++k) sum += at(k);
                for (int k = 0; k < len; ++k) {
                    dst[horizontal ? size_t(l) * size_t(w) + size_t(k) : size_t(k) * size_t(w) + size_t(l)] =
                        static_cast<float>(sum / double(2 * r + 1));
                    sum += at(k + r + 1) - at(k - r);
                }
            }
        });
    };
    for (int i = 0; i < 2; ++i) {
        pass(a, b, true);
        pass(b, a, false);
    }
    return a;
}

} // namespace

std::vector<float> shadingHeights(const Terrain& terrain, int threads) {
    if (terrain.shadeBlur <= 0) return {};
    return smoothed(terrain.z, terrain.width, terrain.height, terrain.shadeBlur, threads);
}

void terrainShadingRows(const Terrain& t, const std::vector<float>& heights, glm::vec3 sun, int j0, int j1,
                        std::vector<float>& out, int threads) {
    assert(0 <= j0 && j0 < j1 && j1 <= t.height && "terrainShadingRows(): rows outside the grid");
    const std::vector<float>& z = heights.empty() ? t.z : heights;
    const int w = t.width, h = t.height;
    out.resize(size_t(j1 - j0) * size_t(w));
    parallelChunks(j1 - j0, 32, threads, [&](int a, int b) {
        for (int j = j0 + a; j < j0 + b; ++j)
            for (int i = 0; i < w; ++i) {
                const int il = std::max(i - 1, 0), ir = std::min(i + 1, w - 1);
                const int jn = std::max(j - 1, 0), js = std::min(j + 1, h - 1);
                const float dzdx = (z[size_t(j) * size_t(w) + size_t(ir)] - z[size_t(j) * size_t(w) + size_t(il)]) /
                                   (float(std::max(ir - il, 1)) * t.spacing);
                const float dzdy = (z[size_t(jn) * size_t(w) + size_t(i)] - z[size_t(js) * size_t(w) + size_t(i)]) /
                                   (float(std::max(js - jn, 1)) * t.spacing);
                const glm::vec3 nrm = glm::normalize(glm::vec3(-dzdx, -dzdy, 1.0f));
                out[size_t(j - j0) * size_t(w) + size_t(i)] = std::max(0.0f, glm::dot(nrm, sun));
            }
    });
}

} // namespace seasonview::synth
