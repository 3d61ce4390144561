#include "Heightfield.h"

#include "GdalSupport.h"
#include "GridReader.h"

#include <glm/common.hpp>

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

namespace {

/// Metres per unit of a DEM band's heights, from GDAL's unit type; nothing for units that are not lengths we know.
std::optional<double> metresPerHeightUnit(const std::string& unit) {
    std::string u;
    for (char c : unit) u += char(std::tolower(static_cast<unsigned char>(c)));
    if (u.empty() || u == "m" || u == "metre" || u == "metres" || u == "meter" || u == "meters") return 1.0;
    if (u == "ft" || u == "foot" || u == "feet" || u == "international foot") return 0.3048;
    if (u == "us survey foot" || u == "ftus" || u == "us-ft" || u == "survey foot") return 1200.0 / 3937.0;
    return std::nullopt;
}

} // namespace

Result<HeightEncoding> parseHeightEncoding(std::string_view text) {
    if (text.empty() || text == "value") return HeightEncoding::Value;
    if (text == "terrarium") return HeightEncoding::Terrarium;
    if (text == "mapbox") return HeightEncoding::Mapbox;
    return Error{"--dem-encoding '" + std::string(text) + "': expected value, terrarium or mapbox"};
}

Result<Heightfield> loadHeightfield(const RasterMosaic& dem, const WorkingGrid& area, HeightEncoding encoding) {
    const RasterInfo& first = dem.tiles.front();
    const std::string name = first.path.string();
    double unit = 1.0;
    if (encoding != HeightEncoding::Value && (dem.bands < 3 || dem.type != SampleType::U8))
        return fileError(name, "heights encoded in colour need 8-bit RGB tiles, not " + std::to_string(dem.bands) +
                                   " band(s) of " + sampleTypeName(dem.type));
    if (encoding == HeightEncoding::Value) {
        auto ds = gdal::openRaster(first.path);
        if (!ds) return ds.error();
        const char* u = (*ds)->GetRasterBand(1)->GetUnitType();
        const auto m = metresPerHeightUnit(u ? u : "");
        if (!m) return fileError(name, std::string("DEM heights in '") + u + "' (metres or feet expected)");
        unit = *m;
    }
    // The area in the DEM's CRS, with a margin, on the finest tile's lattice, cut to where the DEM is.
    RasterMosaic areaMosaic;
    RasterInfo areaInfo;
    areaInfo.width = area.width;
    areaInfo.height = area.height;
    areaInfo.georef = area.georef;
    areaMosaic.tiles = {areaInfo};
    auto [lo, hi] = extentIn(areaMosaic, dem.crs);
    const glm::dvec2 centre = convert(area.georef.crs, dem.crs, area.georef.pixelToCrs({area.width * 0.5, area.height * 0.5}));
    if (!(centre.x >= dem.min.x && centre.x <= dem.max.x && centre.y >= dem.min.y && centre.y <= dem.max.y))
        return fileError(name, "DEM does not cover the imagery (its centre lies outside it)");
    const Georef& f = *dem.finest().georef;
    const glm::dvec2 margin = glm::max(0.25 * (hi - lo), 8.0 * f.pixelSize);
    lo = glm::max(lo - margin, dem.min);
    hi = glm::min(hi + margin, dem.max);
    WorkingGrid g;
    g.georef.crs = dem.crs;
    g.georef.pixelSize = f.pixelSize;
    const double x0 = f.origin.x + std::floor((lo.x - f.origin.x) / f.pixelSize.x) * f.pixelSize.x;
    const double x1 = f.origin.x + std::ceil((hi.x - f.origin.x) / f.pixelSize.x) * f.pixelSize.x;
    const double y0 = f.origin.y + std::floor((lo.y - f.origin.y) / f.pixelSize.y) * f.pixelSize.y;
    const double y1 = f.origin.y + std::ceil((hi.y - f.origin.y) / f.pixelSize.y) * f.pixelSize.y;
    g.georef.origin = {x0, y1};
    g.width = std::max(1, int(std::lround((x1 - x0) / f.pixelSize.x)));
    g.height = std::max(1, int(std::lround((y1 - y0) / f.pixelSize.y)));
    if (std::int64_t(g.width) * g.height > (std::int64_t(1) << 30))
        return fileError(name, "DEM over the scene would be " + std::to_string(g.width) + "x" +
                                   std::to_string(g.height) + " samples (at most 2^30; give a coarser DEM)");

    auto reader = GridReader::open(dem, g, Resampling::Auto, 512);
    if (!reader) return reader.error();
    Heightfield hf;
    hf.georef = g.georef;
    hf.sourceName = std::filesystem::weakly_canonical(std::filesystem::absolute(first.path)).string();
    hf.sourceKey = dem.key + "|" + g.key() + "|unit " + std::to_string(unit) +
                   (encoding == HeightEncoding::Value ? "" : encoding == HeightEncoding::Terrarium ? "|terrarium" : "|mapbox");
    hf.heights.width = g.width;
    hf.heights.height = g.height;
    hf.heights.channels = 1;
    hf.heights.pixels.resize(size_t(g.width) * size_t(g.height));
    std::vector<std::uint8_t> coverage(size_t(g.width) * size_t(reader->bandRows()));
    std::vector<std::uint8_t> rgb;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int y = 0; y < g.height; y += reader->bandRows()) {
        const int y1b = std::min(g.height, y + reader->bandRows());
        float* rows = hf.heights.pixels.data() + size_t(y) * size_t(g.width);
        if (encoding == HeightEncoding::Value) {
            if (auto st = reader->read(y, y1b, 1, SampleType::F32, rows, coverage.data()); !st) return st.error();
        } else {
            // Heights in colour: decoded exactly from the three bytes (read on the DEM's own lattice: not blended).
            const size_t n = size_t(y1b - y) * size_t(g.width);
            rgb.resize(n * 3);
            if (auto st = reader->read(y, y1b, 3, SampleType::U8, rgb.data(), coverage.data()); !st) return st.error();
            for (size_t i = 0; i < n; ++i) {
                const double r = rgb[3 * i], gr = rgb[3 * i + 1], b = rgb[3 * i + 2];
                rows[i] = encoding == HeightEncoding::Terrarium ? float(r * 256.0 + gr + b / 256.0 - 32768.0)
                                                                : float(-10000.0 + (r * 65536.0 + gr * 256.0 + b) * 0.1);
            }
        }
        for (size_t i = 0, n = size_t(y1b - y) * size_t(g.width); i < n; ++i) {
            float& v = rows[i];
            // -32768: SRTM void; |h| > 100 km: garbage (no terrain on Earth is there).
            if (!coverage[i] || !std::isfinite(v) || (encoding == HeightEncoding::Value && first.nodata && double(v) == *first.nodata) || v <= -32767.0f ||
                std::fabs(v) > 1.0e5f)
                v = nan;
            else
                v = float(double(v) * unit);
        }
    }
    const int filled = fillHoles(hf.heights);
    if (filled < 0)
        return fileError(name, "DEM has no valid heights (all " +
                                   std::to_string(size_t(hf.heights.width) * size_t(hf.heights.height)) +
                                   " samples are NaN or nodata)");
    hf.filledSamples = filled;
    auto [mn, mx] = std::minmax_element(hf.heights.pixels.begin(), hf.heights.pixels.end());
    hf.minHeight = *mn;
    hf.maxHeight = *mx;
    return hf;
}

} // namespace seasonview
