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

} // namespace seasonview
