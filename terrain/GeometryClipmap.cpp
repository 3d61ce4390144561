#include "GeometryClipmap.h"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace seasonview {

int geometryLevelCount(int n, int extentSamples) {
    int levels = 1;
    while (levels < 24 && double(n - 1) * std::ldexp(1.0, levels - 1) < 2.0 * double(extentSamples)) ++levels;
    return levels;
}

int finestActiveLevel(int levels, double spacing, double heightAboveTerrain, double pixelsPerRadian) {
    int l = 0;
    const double h = std::max(heightAboveTerrain, 1e-3);
    while (l + 1 < levels && std::ldexp(spacing, l) * pixelsPerRadian / h < kMinCellPixels) ++l;
    return l;
}

GeometryPlacement placeGeometryLevels(glm::dvec2 viewer, int n, int levels, int finest) {
    assert(levels >= 1 && finest >= 0 && finest < levels && "placeGeometryLevels(): bad level range");
    const RingLayout ring = RingLayout::make(n);
    const double half = double(n - 1) / 2.0;
    GeometryPlacement p;
    p.finest = finest;
    p.levels.resize(size_t(levels));
    for (int l = levels - 1; l >= 0; --l) {
        GeometryLevel& g = p.levels[size_t(l)];
        g.cell = 1 << l;
        const double cell = double(g.cell), dbl = 2.0 * cell;
        const glm::dvec2 ideal = viewer - half * cell; // the origin that would centre the level on the viewer
        if (l == levels - 1) {
            g.origin = glm::ivec2(int(std::lround(ideal.x / dbl) * g.cell * 2), int(std::lround(ideal.y / dbl) * g.cell * 2));
            continue;
        }
        GeometryLevel& coarser = p.levels[size_t(l + 1)];
        const int cc = coarser.cell;
        // Inside the coarser level's hole the finer level starts at cell m - 1 (trim on the high side) or m (trim on
        // the low side) of the coarser level.
        auto pick = [&](int coarseOrigin, double want, TrimSide& side) {
            const int lowTrim = coarseOrigin + ring.m * cc, highTrim = coarseOrigin + (ring.m - 1) * cc;
            const bool low = std::abs(double(lowTrim) - want) < std::abs(double(highTrim) - want);
            side = low ? TrimSide::Low : TrimSide::High;
            return low ? lowTrim : highTrim;
        };
        g.origin.x = pick(coarser.origin.x, ideal.x, coarser.trimX);
        g.origin.y = pick(coarser.origin.y, ideal.y, coarser.trimY);
    }
    return p;
}

std::vector<GridRect> levelPieces(const RingLayout& ring, const GeometryPlacement& p, int level) {
    if (level == p.finest) return ring.finestPieces();
    std::vector<GridRect> out = ring.ringBlocks();
    for (const GridRect& r : ring.fixups()) out.push_back(r);
    const GeometryLevel& g = p.levels[size_t(level)];
    for (const GridRect& r : ring.trim(g.trimX, g.trimY)) out.push_back(r);
    return out;
}

FrustumPlanes FrustumPlanes::fromViewProj(const glm::dmat4& m) {
    // Gribb & Hartmann: plane = row 3 ± row k (glm is column-major: m[col][row]).
    auto row = [&](int r) { return glm::dvec4(m[0][r], m[1][r], m[2][r], m[3][r]); };
    FrustumPlanes f;
    f.planes = {row(3) + row(0), row(3) - row(0), row(3) + row(1), row(3) - row(1)};
    return f;
}

bool FrustumPlanes::outside(const glm::dvec3& lo, const glm::dvec3& hi) const {
    for (const glm::dvec4& pl : planes) {
        const glm::dvec3 v(pl.x >= 0 ? hi.x : lo.x, pl.y >= 0 ? hi.y : lo.y, pl.z >= 0 ? hi.z : lo.z);
        if (pl.x * v.x + pl.y * v.y + pl.z * v.z + pl.w < 0) return true;
    }
    return false;
}

HeightBounds HeightBounds::flat(float h) {
    HeightBounds b;
    b.m_levels.push_back({1, 1, {glm::vec2(h, h)}});
    b.m_tileSize = glm::dvec2(1e300);
    return b;
}

HeightBounds HeightBounds::build(int width, int height, int tiles, const TileRange& tileRange) {
    HeightBounds b;
    b.m_gridMax = glm::dvec2(std::max(width - 1, 0), std::max(height - 1, 0));
    Level l0;
    l0.w = std::clamp(tiles, 1, std::max(width, 1));
    l0.h = std::clamp(tiles, 1, std::max(height, 1));
    b.m_tileSize = glm::max(b.m_gridMax, glm::dvec2(1.0)) / glm::dvec2(l0.w, l0.h);
    l0.r.resize(size_t(l0.w) * size_t(l0.h));
    for (int y = 0; y < l0.h; ++y)
        for (int x = 0; x < l0.w; ++x)
            l0.r[size_t(y) * size_t(l0.w) + size_t(x)] =
                tileRange(glm::dvec2(x, y) * b.m_tileSize, glm::dvec2(x + 1, y + 1) * b.m_tileSize);
    b.m_levels.push_back(std::move(l0));
    while (b.m_levels.back().w > 1 || b.m_levels.back().h > 1) {
        const Level& f = b.m_levels.back();
        Level c;
        c.w = (f.w + 1) / 2;
        c.h = (f.h + 1) / 2;
        c.r.assign(size_t(c.w) * size_t(c.h), glm::vec2(1e30f, -1e30f));
        for (int y = 0; y < f.h; ++y)
            for (int x = 0; x < f.w; ++x) {
                glm::vec2& t = c.r[size_t(y / 2) * size_t(c.w) + size_t(x / 2)];
                const glm::vec2 v = f.r[size_t(y) * size_t(f.w) + size_t(x)];
                t = glm::vec2(std::min(t.x, v.x), std::max(t.y, v.y));
            }
        b.m_levels.push_back(std::move(c));
    }
    return b;
}

glm::vec2 HeightBounds::range(glm::dvec2 lo, glm::dvec2 hi) const {
    lo = glm::clamp(lo, glm::dvec2(0.0), m_gridMax);
    hi = glm::clamp(hi, glm::dvec2(0.0), m_gridMax);
    // The level where the box spans at most a few tiles per side; its tiles cover the box.
    for (size_t k = 0; k < m_levels.size(); ++k) {
        const Level& L = m_levels[k];
        const glm::dvec2 size = m_tileSize * std::ldexp(1.0, int(k));
        const int x0 = std::clamp(int(std::floor(lo.x / size.x)), 0, L.w - 1);
        const int y0 = std::clamp(int(std::floor(lo.y / size.y)), 0, L.h - 1);
        const int x1 = std::clamp(int(std::floor(hi.x / size.x)), 0, L.w - 1);
        const int y1 = std::clamp(int(std::floor(hi.y / size.y)), 0, L.h - 1);
        if ((x1 - x0 + 1) * (y1 - y0 + 1) > 16 && k + 1 < m_levels.size()) continue;
        glm::vec2 r(1e30f, -1e30f);
        for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) {
                const glm::vec2 v = L.r[size_t(y) * size_t(L.w) + size_t(x)];
                r = glm::vec2(std::min(r.x, v.x), std::max(r.y, v.y));
            }
        return r;
    }
    return m_levels.back().r[0];
}

} // namespace seasonview
