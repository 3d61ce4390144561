#pragma once
// A DEM in memory: float heights (metres) on its own georeferenced grid, with nodata holes filled.
#include "GeoFrame.h"
#include "Raster.h"
#include "RasterMosaic.h"
#include "WorkingGrid.h"
#include "Result.h"

#include <glm/vec2.hpp>

#include <filesystem>
#include <string_view>

namespace seasonview {

struct Heightfield {
    Image<float> heights;   // one channel, row 0 = north
    Georef georef;
    int filledSamples = 0;  // nodata/NaN samples replaced by push-pull interpolation
    float minHeight = 0, maxHeight = 0;
    std::string sourceName; // the DEM's first file (messages, caches)
    std::string sourceKey;  // its files' identities and the area read: what caches of it key on

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

/// Loads a DEM (any raster GDAL reads, one file or a mosaic of tiles such as SRTM's 1°×1° ones; any CRS) in its own
/// CRS, on its finest tile's lattice, over `area`'s extent plus a margin (a quarter of the area's size, at least 8
/// samples) where the DEM reaches. Heights in metres; a band whose unit is feet (international or US survey) is
/// converted. Samples that are NaN, infinite, nodata (value, mask), outside every tile or -32768 (SRTM voids) are
/// filled from their neighbours. Errors name the file: a DEM that does not cover the area's centre, one with no
/// valid sample, a vertical unit other than metres or feet.
/// `encoding`: how the DEM's samples hold heights: values (the first band, in its unit), or the colour of 8-bit RGB
/// tiles as elevation tile services serve them: Terrarium (h = R·256 + G + B/256 − 32768 m) or Mapbox Terrain-RGB
/// (h = −10000 + (R·65536 + G·256 + B) · 0.1 m); pixels without alpha are no data.
enum class HeightEncoding { Value, Terrarium, Mapbox };
/// "value", "terrarium", "mapbox" (errors name the flag --dem-encoding).
Result<HeightEncoding> parseHeightEncoding(std::string_view text);
Result<Heightfield> loadHeightfield(const RasterMosaic& dem, const WorkingGrid& area,
                                    HeightEncoding encoding = HeightEncoding::Value);

/// Fills NaN samples of `img` from their valid neighbours (push-pull over a mip pyramid); returns how many were
/// filled. Returns -1 when no sample is valid.
int fillHoles(Image<float>& img);

} // namespace seasonview
