#include "Heightfield.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace seasonview {

namespace {

/// The four samples around a point (pixel-centre convention, clamped to the grid) and its position between them.
struct Cell {
    double h00, h10, h01, h11, fx, fy;
};

Cell cellAt(const Heightfield& f, glm::dvec2 p) {
    const glm::dvec2 px = f.georef.crsToPixel(p) - 0.5; // pixel centres
    const double x = std::clamp(px.x, 0.0, double(f.heights.width - 1));
    const double y = std::clamp(px.y, 0.0, double(f.heights.height - 1));
    const int x0 = std::min(int(x), f.heights.width - 1), y0 = std::min(int(y), f.heights.height - 1);
    const int x1 = std::min(x0 + 1, f.heights.width - 1), y1 = std::min(y0 + 1, f.heights.height - 1);
    return {f.heights.at(x0, y0), f.heights.at(x1, y0), f.heights.at(x0, y1), f.heights.at(x1, y1), x - x0, y - y0};
}

} // namespace

double Heightfield::sampleCrs(glm::dvec2 p) const {
    const Cell c = cellAt(*this, p);
    const double a = c.h00 * (1 - c.fx) + c.h10 * c.fx;
    const double b = c.h01 * (1 - c.fx) + c.h11 * c.fx;
    return a * (1 - c.fy) + b * c.fy;
}

double Heightfield::sampleCrsTriangulated(glm::dvec2 p) const {
    const Cell c = cellAt(*this, p);
    if (c.fx + c.fy <= 1.0) return c.h00 + c.fx * (c.h10 - c.h00) + c.fy * (c.h01 - c.h00);
    return c.h11 + (1.0 - c.fx) * (c.h01 - c.h11) + (1.0 - c.fy) * (c.h10 - c.h11);
}

int fillHoles(Image<float>& img) {
    const int w = img.width, h = img.height;
    int holes = 0;
    for (float v : img.pixels) holes += std::isnan(v) ? 1 : 0;
    if (holes == 0) return 0;
    if (holes == w * h) return -1;
    // Push: average valid samples into a half-size level; recurse; pull: fill holes from the coarser level.
    if (w == 1 && h == 1) return holes;
    Image<float> coarse;
    coarse.width = (w + 1) / 2;
    coarse.height = (h + 1) / 2;
    coarse.channels = 1;
    coarse.pixels.assign(size_t(coarse.width) * size_t(coarse.height), std::numeric_limits<float>::quiet_NaN());
    for (int y = 0; y < coarse.height; ++y)
        for (int x = 0; x < coarse.width; ++x) {
            double sum = 0;
            int n = 0;
            for (int dy = 0; dy < 2; ++dy)
                for (int dx = 0; dx < 2; ++dx) {
                    const int sx = 2 * x + dx, sy = 2 * y + dy;
                    if (sx >= w || sy >= h) continue;
                    const float v = img.at(sx, sy);
                    if (!std::isnan(v)) {
                        sum += v;
                        ++n;
                    }
                }
            if (n) coarse.at(x, y) = float(sum / n);
        }
    fillHoles(coarse);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            if (std::isnan(img.at(x, y))) {
                // Bilinear from the coarse level at this sample's centre.
                const double cx = std::clamp((x + 0.5) / 2.0 - 0.5, 0.0, double(coarse.width - 1));
                const double cy = std::clamp((y + 0.5) / 2.0 - 0.5, 0.0, double(coarse.height - 1));
                const int x0 = int(cx), y0 = int(cy);
                const int x1 = std::min(x0 + 1, coarse.width - 1), y1 = std::min(y0 + 1, coarse.height - 1);
                const double fx = cx - x0, fy = cy - y0;
                img.at(x, y) = float((coarse.at(x0, y0) * (1 - fx) + coarse.at(x1, y0) * fx) * (1 - fy) +
                                     (coarse.at(x0, y1) * (1 - fx) + coarse.at(x1, y1) * fx) * fy);
            }
    return holes;
}

Result<Heightfield> loadHeightfield(const std::filesystem::path& path) {
    auto info = readRasterInfo(path);
    if (!info) return info.error();
    if (!info->georef) return fileError(path.string(), "DEM has no GeoTIFF georeferencing");
    if (info->channels < 1) return fileError(path.string(), "DEM has no bands");
    auto img = readImageF32(path, 1);
    if (!img) return img.error();
    Heightfield hf;
    hf.heights = std::move(*img);
    hf.georef = *info->georef;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (float& v : hf.heights.pixels) {
        // -32768: SRTM void; |h| > 100 km: garbage (no terrain on Earth is there).
        if (!std::isfinite(v) || (info->nodata && double(v) == *info->nodata) || v <= -32767.0f ||
            std::fabs(v) > 1.0e5f)
            v = nan;
    }
    const int filled = fillHoles(hf.heights);
    if (filled < 0)
        return fileError(path.string(), "DEM has no valid heights (all " +
                                            std::to_string(size_t(hf.heights.width) * size_t(hf.heights.height)) +
                                            " samples are NaN or nodata)");
    hf.filledSamples = filled;
    auto [mn, mx] = std::minmax_element(hf.heights.pixels.begin(), hf.heights.pixels.end());
    hf.minHeight = *mn;
    hf.maxHeight = *mx;
    return hf;
}

} // namespace seasonview
