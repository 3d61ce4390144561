#include "ElevationPyramid.h"

#include "GeoTiffStreamWriter.h"
#include "PyramidBuilder.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>

namespace seasonview {

namespace {

/// Writes one level as a tiled, Zstandard-compressed single-channel float TIFF (content checksums, as the imagery
/// pyramids' levels), through the writer whose bytes depend only on the samples: a rebuilt level is byte-identical.
Status writeLevel(const std::filesystem::path& file, const std::vector<float>& heights, int w, int h, int tileSize) {
    GeoTiffWriteOptions o;
    o.tileSize = tileSize;
    o.compression = TiffCompression::Zstd;
    auto out = GeoTiffStreamWriter::open(file, w, h, 1, SampleType::F32, std::nullopt, o);
    if (!out) return out.error();
    if (auto st = out->writeRows(0, h, heights.data()); !st) return st.error();
    return out->finish();
}

} // namespace

ElevationGrid elevationGrid(const Scene& scene) {
    ElevationGrid g;
    const glm::dvec2 extent = scene.localMax - scene.localMin;
    double margin = 0.0;
    if (scene.elevation) {
        const Heightfield& dem = *scene.elevation;
        const Georef& r = dem.georef;
        // The grid starts at the imagery's corner, so it rarely falls on the DEM's own samples: it takes the DEM's
        // finest spacing (measured in local metres at its centre) for a DEM in the frame's own UTM zone, and half
        // of it for other CRSs (EPSG:4326, other zones), keeping the resampled surface close to the DEM's own
        // triangulated one, as long as the grid stays within 16384 samples per side.
        const bool sameSpace = scene.frame.isTranslation() && r.crs == scene.frame.crs();
        const glm::dvec2 c(double(dem.heights.width) / 2.0, double(dem.heights.height) / 2.0);
        auto local = [&](glm::dvec2 px) { return glm::dvec2(scene.frame.toLocal(r.crs, r.pixelToCrs(px))); };
        const glm::dvec2 p0 = local(c);
        const double native = std::min(glm::length(local(c + glm::dvec2(1, 0)) - p0),
                                       glm::length(local(c + glm::dvec2(0, 1)) - p0));
        const double widest = std::max(extent.x, extent.y) + 4.0 * native;
        g.spacing = !sameSpace && widest / (native / 2.0) <= 16384.0 ? native / 2.0 : native;
        margin = 2.0 * native;
        g.origin = {scene.localMin.x - margin, scene.localMax.y + margin};
        if (sameSpace && g.spacing == native) {
            // In the DEM's own space and spacing: start on one of its samples (north-west of the corner), so every
            // grid sample is a DEM sample and the grid's triangulated surface is the DEM's, not a smoothed copy.
            const glm::dvec2 px = glm::floor(r.crsToPixel(scene.frame.fromLocal(r.crs, g.origin)) - 0.5);
            g.origin = glm::dvec2(scene.frame.toLocal(r.crs, r.pixelToCrs(px + 0.5)));
        }
    } else {
        g.spacing = std::max(scene.gsd, std::max(extent.x, extent.y) / 2048.0);
        margin = 2.0 * g.spacing;
        g.origin = {scene.localMin.x - margin, scene.localMax.y + margin};
    }
    g.width = int(std::ceil((scene.localMax.x + margin - g.origin.x) / g.spacing)) + 1;
    g.height = int(std::ceil((g.origin.y - (scene.localMin.y - margin)) / g.spacing)) + 1;
    return g;
}

std::vector<float> resampleElevation(const Scene& scene, const ElevationGrid& grid) {
    assert(scene.elevation && "resampleElevation(): the scene has no DEM");
    const Heightfield& dem = *scene.elevation;
    constexpr int kStep = 16;
    const int lw = (grid.width + kStep - 1) / kStep + 1, lh = (grid.height + kStep - 1) / kStep + 1;
    std::vector<glm::dvec2> lattice(size_t(lw) * size_t(lh));
    for (int j = 0; j < lh; ++j)
        for (int i = 0; i < lw; ++i)
            lattice[size_t(j) * size_t(lw) + size_t(i)] =
                scene.frame.fromLocal(dem.georef.crs, grid.samplePosition(double(i * kStep), double(j * kStep)));
    std::vector<float> out(size_t(grid.width) * size_t(grid.height));
    for (int y = 0; y < grid.height; ++y) {
        const int ly = y / kStep;
        const double fy = double(y % kStep) / kStep;
        for (int x = 0; x < grid.width; ++x) {
            const int lx = x / kStep;
            const double fx = double(x % kStep) / kStep;
            auto at = [&](int i, int j) { return lattice[size_t(ly + j) * size_t(lw) + size_t(lx + i)]; };
            const glm::dvec2 p = (at(0, 0) * (1 - fx) + at(1, 0) * fx) * (1 - fy) + (at(0, 1) * (1 - fx) + at(1, 1) * fx) * fy;
            out[size_t(y) * size_t(grid.width) + size_t(x)] = float(dem.sampleCrsTriangulated(p));
        }
    }
    return out;
}

PyramidSource elevationPyramidSource(const Scene& scene, const ElevationGrid& grid) {
    assert(scene.elevation && "elevationPyramidSource(): the scene has no DEM");
    PyramidSource s;
    s.name = "elevation from " + scene.elevation->sourceName;
    char params[160];
    std::snprintf(params, sizeof params, "elevation r32f triangulated|%.9g|%.6f,%.6f|%dx%d|", grid.spacing, grid.origin.x,
                  grid.origin.y, grid.width, grid.height);
    s.identity = scene.elevation->sourceKey + "|" + params + scene.frame.crs().identifier() +
                 (scene.frame.isTranslation() ? "|translation" : "|tangent plane");
    s.width = grid.width;
    s.height = grid.height;
    s.format = TexelFormat::R32F;
    s.build = [&scene, grid](const std::filesystem::path& folder, int tileSize,
                             const ProgressFn& progress) -> Result<std::vector<PyramidLevel>> {
        if (progress) progress(0.0, "resampling the DEM");
        std::vector<float> level = resampleElevation(scene, grid);
        const auto sizes = pyramidLevelSizes(grid.width, grid.height);
        std::vector<PyramidLevel> levels;
        int w = grid.width;
        for (size_t k = 0; k < sizes.size(); ++k) {
            const auto [lw, lh] = sizes[k];
            if (k > 0) { // every other sample of the finer level
                std::vector<float> next(size_t(lw) * size_t(lh));
                for (int y = 0; y < lh; ++y)
                    for (int x = 0; x < lw; ++x)
                        next[size_t(y) * size_t(lw) + size_t(x)] = level[size_t(2 * y) * size_t(w) + size_t(2 * x)];
                level = std::move(next);
            }
            w = lw;
            PyramidLevel pl{folder / pyramidLevelFileName(int(k)), lw, lh};
            if (auto st = writeLevel(pl.file, level, lw, lh, tileSize); !st) return st.error();
            levels.push_back(std::move(pl));
            if (progress) progress(double(k + 1) / double(sizes.size()), "elevation levels");
        }
        return levels;
    };
    return s;
}

} // namespace seasonview
