#include "WorkingGrid.h"

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <span>
#include <tuple>
#include <vector>

namespace seasonview {

namespace {

/// A tile's outline in `crs`: 32 points per edge (projections curve straight edges).
void outline(const RasterInfo& t, const Crs& crs, glm::dvec2& lo, glm::dvec2& hi) {
    constexpr int kPerEdge = 32;
    std::vector<glm::dvec2> pts;
    pts.reserve(4 * kPerEdge);
    const Georef& g = *t.georef;
    for (int i = 0; i < kPerEdge; ++i) {
        const double f = double(i) / kPerEdge;
        pts.push_back(g.pixelToCrs({f * t.width, 0.0}));
        pts.push_back(g.pixelToCrs({t.width, f * t.height}));
        pts.push_back(g.pixelToCrs({(1.0 - f) * t.width, double(t.height)}));
        pts.push_back(g.pixelToCrs({0.0, (1.0 - f) * t.height}));
    }
    convert(g.crs, crs, std::span<glm::dvec2>(pts));
    for (const glm::dvec2& p : pts) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
}

/// The size of `tile`'s pixel at its centre, measured in `crs` (its own pixel size when it is in `crs`).
glm::dvec2 pixelIn(const RasterInfo& t, const Crs& crs) {
    const Georef& g = *t.georef;
    if (g.crs == crs) return g.pixelSize;
    const glm::dvec2 c(t.width * 0.5, t.height * 0.5);
    glm::dvec2 p[3] = {g.pixelToCrs(c), g.pixelToCrs(c + glm::dvec2(1.0, 0.0)), g.pixelToCrs(c + glm::dvec2(0.0, 1.0))};
    convert(g.crs, crs, std::span<glm::dvec2>(p, 3));
    const double area = glm::length(p[1] - p[0]) * glm::length(p[2] - p[0]);
    // Four significant digits: 12.08 m, not 12.0837161 m.
    double side = std::sqrt(area);
    if (!(side > 0.0) || !std::isfinite(side)) return glm::dvec2(std::numeric_limits<double>::quiet_NaN());
    const double scale = std::pow(10.0, 3 - std::floor(std::log10(side)));
    side = std::round(side * scale) / scale;
    return glm::dvec2(side);
}

std::string extentText(glm::dvec2 lo, glm::dvec2 hi) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "%.2f..%.2f, %.2f..%.2f", lo.x, hi.x, lo.y, hi.y);
    return buf;
}

} // namespace

std::string WorkingGrid::key() const {
    char buf[200];
    std::snprintf(buf, sizeof buf, "|%.17g,%.17g|%.17g,%.17g|%dx%d", georef.origin.x, georef.origin.y,
                  georef.pixelSize.x, georef.pixelSize.y, width, height);
    return georef.crs.identifier() + buf;
}

std::pair<glm::dvec2, glm::dvec2> extentIn(const RasterMosaic& m, const Crs& crs) {
    glm::dvec2 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
    for (const RasterInfo& t : m.tiles) outline(t, crs, lo, hi);
    return {lo, hi};
}

std::pair<glm::dvec2, glm::dvec2> boxIn(glm::dvec2 lo, glm::dvec2 hi, const Crs& from, const Crs& to) {
    if (from == to) return {lo, hi};
    constexpr int kPerEdge = 32;
    std::vector<glm::dvec2> pts;
    for (int i = 0; i < kPerEdge; ++i) {
        const double f = double(i) / kPerEdge;
        pts.push_back({lo.x + f * (hi.x - lo.x), lo.y});
        pts.push_back({hi.x, lo.y + f * (hi.y - lo.y)});
        pts.push_back({hi.x - f * (hi.x - lo.x), hi.y});
        pts.push_back({lo.x, hi.y - f * (hi.y - lo.y)});
    }
    convert(from, to, std::span<glm::dvec2>(pts));
    glm::dvec2 a(std::numeric_limits<double>::max()), b(std::numeric_limits<double>::lowest());
    int converted = 0;
    for (const glm::dvec2& p : pts)
        if (std::isfinite(p.x) && std::isfinite(p.y)) a = glm::min(a, p), b = glm::max(b, p), ++converted;
    if (converted == 0) return {glm::dvec2(std::nan("")), glm::dvec2(std::nan(""))}; // not expressible in `to`
    return {a, b};
}

Crs defaultGridCrs(const Crs& crs, glm::dvec2 lo, glm::dvec2 hi) {
    if (!crs.isGeographic()) return crs;
    const glm::dvec2 c = convert(crs, Crs::geographic(), 0.5 * (lo + hi));
    return Crs::utmAt(c.x, c.y);
}

bool onGridLattice(const RasterInfo& tile, const WorkingGrid& grid) {
    if (!tile.georef || tile.georef->crs != grid.georef.crs) return false;
    const Georef& t = *tile.georef;
    const Georef& g = grid.georef;
    auto same = [](double a, double b) { return std::abs(a - b) <= 1e-9 * std::abs(b); };
    if (!same(t.pixelSize.x, g.pixelSize.x) || !same(t.pixelSize.y, g.pixelSize.y)) return false;
    const glm::dvec2 shift = g.crsToPixel(t.origin);
    return std::abs(shift.x - std::round(shift.x)) < 1e-6 && std::abs(shift.y - std::round(shift.y)) < 1e-6;
}

Result<WorkingGrid> chooseWorkingGrid(const RasterMosaic& on, const RasterMosaic& off, const GridOptions& options,
                                      const std::string& onName, const std::string& offName) {
    WorkingGrid grid;
    // CRS.
    grid.georef.crs = options.crs ? *options.crs : defaultGridCrs(on.crs, on.min, on.max);
    const Crs& crs = grid.georef.crs;

    // Extents in the grid's CRS, and their overlap.
    const auto [onLo, onHi] = extentIn(on, crs);
    const auto [offLo, offHi] = extentIn(off, crs);
    auto finite = [](glm::dvec2 a, glm::dvec2 b) {
        return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(b.x) && std::isfinite(b.y);
    };
    if (!finite(onLo, onHi)) return fileError(onName, "cannot be expressed in the grid's CRS " + crs.name());
    if (!finite(offLo, offHi)) return fileError(offName, "cannot be expressed in the grid's CRS " + crs.name());
    const glm::dvec2 interLo = glm::max(onLo, offLo), interHi = glm::min(onHi, offHi);
    if (!(interLo.x < interHi.x && interLo.y < interHi.y))
        return fileError(offName, "does not overlap the leaf-on " + onName + " (in " + crs.name() + ": leaf-off " +
                                      extentText(offLo, offHi) + ", leaf-on " + extentText(onLo, onHi) + ")");

    // Pixel size: the finest season's.
    const RasterInfo* finest = nullptr;
    glm::dvec2 pixel(0.0);
    for (const RasterMosaic* m : {&on, &off}) {
        const RasterInfo& t = m->finest();
        const glm::dvec2 p = pixelIn(t, crs);
        if (!std::isfinite(p.x) || !std::isfinite(p.y))
            return fileError(t.path.string(), "its pixel size cannot be measured in " + crs.name());
        if (!finest || p.x * p.y < pixel.x * pixel.y) {
            finest = &t;
            pixel = p;
        }
    }
    if (options.resolution) pixel = glm::dvec2(*options.resolution);
    grid.georef.pixelSize = pixel;

    // Extent, snapped outwards to the alignment lattice.
    glm::dvec2 lo = glm::min(onLo, offLo), hi = glm::max(onHi, offHi);
    if (options.extent) {
        lo = {(*options.extent)[0], (*options.extent)[1]};
        hi = {(*options.extent)[2], (*options.extent)[3]};
        if (!(lo.x < hi.x && lo.y < hi.y)) return Error{"--extent: xmin < xmax and ymin < ymax expected"};
        if (options.extentCrs) {
            std::tie(lo, hi) = boxIn(lo, hi, *options.extentCrs, crs);
            if (!finite(lo, hi)) return Error{"--extent cannot be expressed in the grid's CRS " + crs.name()};
        }
        if (!(lo.x < interHi.x && lo.y < interHi.y && hi.x > interLo.x && hi.y > interLo.y))
            return Error{"--extent " + extentText(lo, hi) + " lies outside the area both seasons cover (" +
                         extentText(interLo, interHi) + " in " + crs.name() + ")"};
    }
    glm::dvec2 anchor(0.0);
    if (finest->georef->crs == crs && finest->georef->pixelSize == pixel) anchor = finest->georef->origin;
    else if (on.tiles.front().georef->crs == crs && on.tiles.front().georef->pixelSize == pixel)
        anchor = on.tiles.front().georef->origin;
    constexpr double eps = 1e-6; // pixels: extents that lie on the lattice stay where they are
    const double x0 = anchor.x + std::floor((lo.x - anchor.x) / pixel.x + eps) * pixel.x;
    const double x1 = anchor.x + std::ceil((hi.x - anchor.x) / pixel.x - eps) * pixel.x;
    const double y0 = anchor.y + std::floor((lo.y - anchor.y) / pixel.y + eps) * pixel.y;
    const double y1 = anchor.y + std::ceil((hi.y - anchor.y) / pixel.y - eps) * pixel.y;
    const double w = std::round((x1 - x0) / pixel.x), h = std::round((y1 - y0) / pixel.y);
    if (!(w >= 1.0 && h >= 1.0)) return Error{"scene: the working grid has no pixels"};
    if (w > kMaxGridSide || h > kMaxGridSide) {
        char buf[240];
        std::snprintf(buf, sizeof buf,
                      "scene: the working grid would be %.0fx%.0f pixels of %.4g %s (at most %d per side; choose a "
                      "coarser --grid-res or a smaller --extent)",
                      w, h, pixel.x, crs.isGeographic() ? "degrees" : "units", kMaxGridSide);
        return Error{buf};
    }
    grid.georef.origin = {x0, y1};
    grid.width = int(w);
    grid.height = int(h);
    return grid;
}

} // namespace seasonview
