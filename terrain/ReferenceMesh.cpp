#include "ReferenceMesh.h"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace seasonview {

namespace {

void gridIndices(ReferenceMesh& m) {
    m.indices.reserve(size_t(m.columns - 1) * size_t(m.rows - 1) * 6);
    for (int j = 0; j + 1 < m.rows; ++j)
        for (int i = 0; i + 1 < m.columns; ++i) {
            const auto a = std::uint32_t(j * m.columns + i), b = a + 1, c = a + std::uint32_t(m.columns), d = c + 1;
            m.indices.insert(m.indices.end(), {a, c, b, b, c, d});
        }
}

} // namespace

ReferenceMesh buildReferenceMesh(const Scene& scene, int flatCells, std::int64_t maxVertices) {
    ReferenceMesh m;
    const Georef& img = *scene.leafon.info.georef;
    const double w = scene.leafon.info.width, h = scene.leafon.info.height;
    auto uvOf = [&](glm::dvec2 imageCrs) {
        const glm::dvec2 p = img.crsToPixel(imageCrs);
        return glm::vec2(float(p.x / w), float(p.y / h));
    };
    if (!scene.elevation) {
        m.columns = m.rows = flatCells + 1;
        m.vertices.reserve(size_t(m.columns) * size_t(m.rows));
        for (int j = 0; j < m.rows; ++j)
            for (int i = 0; i < m.columns; ++i) {
                const glm::dvec2 crs = img.pixelToCrs({w * i / flatCells, h * j / flatCells});
                const glm::dvec3 p = scene.frame.toLocal(img.crs, crs, 0.0);
                m.vertices.push_back({float(p.x), float(p.y), float(p.z), float(i) / float(flatCells),
                                      float(j) / float(flatCells)});
            }
        gridIndices(m);
        return m;
    }
    const Heightfield& hf = *scene.elevation;
    const Georef& dem = hf.georef;
    // DEM sample range covering the imagery (corners and edge midpoints, since CRSs may differ).
    glm::dvec2 lo(1e300), hi(-1e300);
    for (int i = 0; i <= 8; ++i)
        for (int k = 0; k <= 8; ++k) {
            const glm::dvec2 p = dem.crsToPixel(convert(img.crs, dem.crs, img.pixelToCrs({w * i / 8.0, h * k / 8.0})));
            lo = glm::min(lo, p);
            hi = glm::max(hi, p);
        }
    const int x0 = std::clamp(int(std::floor(lo.x - 0.5)) - 1, 0, hf.heights.width - 1);
    const int y0 = std::clamp(int(std::floor(lo.y - 0.5)) - 1, 0, hf.heights.height - 1);
    const int x1 = std::clamp(int(std::ceil(hi.x - 0.5)) + 1, 0, hf.heights.width - 1);
    const int y1 = std::clamp(int(std::ceil(hi.y - 0.5)) + 1, 0, hf.heights.height - 1);
    const std::int64_t samples = std::int64_t(x1 - x0 + 1) * std::int64_t(y1 - y0 + 1);
    m.stride = 1;
    while (samples / (std::int64_t(m.stride) * m.stride) > maxVertices) ++m.stride;
    m.columns = (x1 - x0) / m.stride + 1;
    m.rows = (y1 - y0) / m.stride + 1;
    if (m.columns < 2 || m.rows < 2) { // DEM coarser than the imagery: keep at least one cell
        m.columns = std::max(m.columns, 2);
        m.rows = std::max(m.rows, 2);
    }
    m.vertices.reserve(size_t(m.columns) * size_t(m.rows));
    for (int j = 0; j < m.rows; ++j)
        for (int i = 0; i < m.columns; ++i) {
            const int sx = std::min(x0 + i * m.stride, hf.heights.width - 1);
            const int sy = std::min(y0 + j * m.stride, hf.heights.height - 1);
            const glm::dvec2 crs = dem.pixelToCrs({sx + 0.5, sy + 0.5});
            const glm::dvec3 p = scene.frame.toLocal(dem.crs, crs, hf.heights.at(sx, sy));
            const glm::vec2 uv = uvOf(convert(dem.crs, img.crs, crs));
            m.vertices.push_back({float(p.x), float(p.y), float(p.z), uv.x, uv.y});
        }
    gridIndices(m);
    return m;
}

TileLayout computeTileLayout(int imageWidth, int imageHeight, int maxSize) {
    assert(imageWidth > 0 && imageHeight > 0 && maxSize >= 16 && "computeTileLayout(): bad arguments");
    TileLayout t;
    if (imageWidth <= maxSize && imageHeight <= maxSize) {
        t.tileWidth = imageWidth;
        t.tileHeight = imageHeight;
        return t;
    }
    t.border = 1;
    t.tileWidth = t.tileHeight = maxSize;
    t.step = maxSize - 2 * t.border;
    t.tilesX = (imageWidth + t.step - 1) / t.step;
    t.tilesY = (imageHeight + t.step - 1) / t.step;
    return t;
}

} // namespace seasonview
