#pragma once
// A DEM in memory: float heights (metres) on its own georeferenced grid, with nodata holes filled.
#include "GeoFrame.h"
#include "Raster.h"
#include "Result.h"

#include <glm/vec2.hpp>

#include <filesystem>

namespace seasonview {

struct Heightfield {
    Image<float> heights;   // one channel, row 0 = north
    Georef georef;
    int filledSamples = 0;  // nodata/NaN samples replaced by push-pull interpolation
    float minHeight = 0, maxHeight = 0;

    /// Bilinear height at a point in the DEM's CRS (clamped to the grid's edge samples).
    double sampleCrs(glm::dvec2 p) const;
    /// The height of the DEM's triangulated surface at a point in its CRS: each cell between four sample centres
    /// split along its north-east to south-west diagonal, the surface the reference mesh draws
    /// (terrain/ReferenceMesh.h). Clamped to the grid's edge samples.
    double sampleCrsTriangulated(glm::dvec2 p) const;
    /// Bilinear height under a local-frame point (metres) of `frame`.
    double sampleLocal(const GeoFrame& frame, glm::dvec2 local) const {
        return sampleCrs(frame.fromLocal(georef.crs, local));
    }
};

/// Loads a DEM (float32 or int16 GeoTIFF, geographic or UTM). Samples that are NaN, infinite, equal to the file's
/// nodata value or -32768 (SRTM voids) are nodata and get filled; a DEM with no valid sample, or without
/// georeferencing, is an error naming the file.
Result<Heightfield> loadHeightfield(const std::filesystem::path& path);

/// Fills NaN samples of `img` from their valid neighbours (push-pull over a mip pyramid); returns how many were
/// filled. Returns -1 when no sample is valid.
int fillHoles(Image<float>& img);

} // namespace seasonview
