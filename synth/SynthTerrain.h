#pragma once
// Elevation of a synthetic scene: fBm lowland terrain with a carved river valley, or a crop of a real DEM
// resampled onto the scene's UTM grid. The grid covers exactly the imagery's extent (pixel-is-area, row 0 north)
// with a coarser spacing than the imagery; everything finer is bilinear.
#include "Crs.h"
#include "Raster.h"
#include "Result.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <vector>

namespace seasonview::synth {

struct Layout;

struct Terrain {
    int width = 0, height = 0;  // samples
    float spacing = 1.0f;       // metres between samples
    float halfExtent = 0.0f;    // covers [-halfExtent, halfExtent]² of the local frame; sample (i,j) at the centre
                                // of cell i,j: x = -halfExtent + (i + 0.5) * spacing, y = halfExtent - (j + 0.5) * spacing
    std::vector<float> z;       // metres above the geoid, row-major, row 0 = north
    int shadeBlur = 0;          // box radius (samples) smoothing z before shading: hides the facets that
                                // bilinear upsampling of a coarse source DEM leaves in the hillshade

    /// Bilinear value of a per-sample field (z or a shading grid) at fractional sample coordinates, clamped.
    float bilinear(const std::vector<float>& f, float fx, float fy) const { return bilinearRows(f.data(), 0, fx, fy); }
    /// The same for a field of which only some rows are held: `rows` points at row `firstRow` (width samples per
    /// row); the rows that fy reads (rowsRead()) must be among them. Bit-identical to bilinear(). Inline: it is in
    /// the inner loops of the shadow sweep and the painter.
    float bilinearRows(const float* rows, int firstRow, float fx, float fy) const {
        fx = std::clamp(fx, 0.0f, float(width - 1));
        fy = std::clamp(fy, 0.0f, float(height - 1));
        const int i = std::min(int(fx), width - 2 < 0 ? 0 : width - 2);
        const int j = std::min(int(fy), height - 2 < 0 ? 0 : height - 2);
        const int i1 = std::min(i + 1, width - 1), j1 = std::min(j + 1, height - 1);
        const float tx = fx - float(i), ty = fy - float(j);
        const size_t w = size_t(width), r0 = size_t(j - firstRow), r1 = size_t(j1 - firstRow);
        const float a = rows[r0 * w + size_t(i)], b = rows[r0 * w + size_t(i1)];
        const float c = rows[r1 * w + size_t(i)], d = rows[r1 * w + size_t(i1)];
        return (a + (b - a) * tx) + ((c + (d - c) * tx) - (a + (b - a) * tx)) * ty;
    }
    /// The first and last sample row that bilinear() reads at fractional row fy.
    void rowsRead(float fy, int& first, int& last) const;
    /// Height (metres) at a local point, bilinear, clamped at the border.
    float sample(glm::vec2 local) const {
        return bilinear(z, (local.x + halfExtent) / spacing - 0.5f, (halfExtent - local.y) / spacing - 0.5f);
    }
};

/// fBm lowland terrain (Münsterland-like: ~40-90 m, gentle slopes) with a valley carved along the layout's river.
Terrain makeFbmTerrain(int samples, float spacing, const Layout& layout, std::uint64_t seed, int threads);

/// A real DEM opened for resampling.
struct DemSource {
    std::filesystem::path path;
    RasterInfo info;              // georef always present
    Image<float> image;
    glm::dvec2 centreLonLat{0.0}; // centre of the DEM's extent
};

/// Opens a DEM (any supported CRS). Errors: unreadable, not georeferenced.
Result<DemSource> openDem(const std::filesystem::path& path);

/// Resamples the DEM onto the scene grid (UTM `sceneCrs`, grid centre at `centre` in UTM metres): bilinear over valid
/// samples (nodata, NaN and SRTM voids < -1000 m are skipped), holes and parts outside the DEM filled from their
/// neighbours. Error when no sample of the scene's extent is valid.
Result<Terrain> resampleDem(const DemSource& dem, int samples, float spacing, const Crs& sceneCrs, glm::dvec2 centre,
                            int threads);

/// The heights that terrain shading sees: z smoothed by `shadeBlur` (a copy, made once for both seasons), or an
/// empty vector when shadeBlur is 0 (shading then reads z itself).
std::vector<float> shadingHeights(const Terrain& terrain, int threads);

/// Rows [j0, j1) of the per-sample cosine between the terrain normal and the unit vector towards the sun (x east,
/// y north, z up), >= 0, into `out` ((j1 - j0) × width). `heights` is shadingHeights() (or terrain.z when that is
/// empty). Each sample depends only on its neighbours, so bands of rows give the same values as the whole grid.
void terrainShadingRows(const Terrain& terrain, const std::vector<float>& heights, glm::vec3 towardSun, int j0, int j1,
                        std::vector<float>& out, int threads);

} // namespace seasonview::synth
