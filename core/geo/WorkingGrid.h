#pragma once
// The scene's working grid: the one north-up grid (CRS, origin, pixel size, size) both seasons are read on, whatever
// grids, resolutions and CRSs they were delivered in. `prepare` warps each season onto it; segmentation masks and
// every other georeferenced output are written on it.
#include "Raster.h"
#include "RasterMosaic.h"
#include "Result.h"

#include <array>
#include <optional>
#include <string>

namespace seasonview {

/// What the user may fix about the grid (--grid-crs, --grid-res, --extent); everything else is chosen.
struct GridOptions {
    std::optional<Crs> crs;
    std::optional<double> resolution;            // grid CRS units per pixel (square pixels)
    std::optional<std::array<double, 4>> extent; // xmin, ymin, xmax, ymax in extentCrs
    std::optional<Crs> extentCrs;                // absent: the grid's CRS; else the box is transformed into it
};

struct WorkingGrid {
    Georef georef;
    int width = 0, height = 0;
    /// The grid's extent in its CRS.
    glm::dvec2 min() const { return {georef.origin.x, georef.origin.y - georef.pixelSize.y * height}; }
    glm::dvec2 max() const { return {georef.origin.x + georef.pixelSize.x * width, georef.origin.y}; }
    /// "EPSG:2154|origin|pixel|size": what caches of data on this grid key on.
    std::string key() const;
};

/// Largest grid side: the synthetic generator's and the pyramid's limit.
inline constexpr int kMaxGridSide = 131072;

/// The working grid of a season pair.
/// - CRS: options.crs; else the leaf-on's when it is projected; else (geographic leaf-on) the UTM zone of the
///   scene's centre.
/// - Pixel size: options.resolution; else the finest season's: exactly its pixel when it is in the grid's CRS, else
///   its pixel's area measured in the grid's CRS at its centre (square root, 4 significant digits).
/// - Extent: options.extent (its outline transformed from options.extentCrs into the grid's CRS, edges sampled at 32
///   points each); else the union of both seasons (their outlines transformed into the grid's CRS).
/// - Alignment: pixel corners on the finest season's own pixel grid when it is in the grid's CRS at the grid's
///   pixel size (so it is read as it is, not resampled), else on multiples of the pixel size.
/// Errors: seasons whose extents do not overlap (naming both), a grid larger than kMaxGridSide per side (naming
/// the options that shrink it), a CRS in which a season cannot be expressed.
Result<WorkingGrid> chooseWorkingGrid(const RasterMosaic& leafon, const RasterMosaic& leafoff,
                                      const GridOptions& options, const std::string& leafonName,
                                      const std::string& leafoffName);

/// The outline of a mosaic's extent in another CRS: its bounding box there (edges sampled at 32 points each).
std::pair<glm::dvec2, glm::dvec2> extentIn(const RasterMosaic& m, const Crs& crs);

/// The bounding box in `to` of the box lo..hi in `from` (edges sampled at 32 points each).
std::pair<glm::dvec2, glm::dvec2> boxIn(glm::dvec2 lo, glm::dvec2 hi, const Crs& from, const Crs& to);

/// The grid CRS chooseWorkingGrid picks without --grid-crs for a leaf-on in `crs` covering lo..hi (in `crs`).
Crs defaultGridCrs(const Crs& crs, glm::dvec2 lo, glm::dvec2 hi);

/// Whether `tile` lies exactly on `grid`'s pixel lattice at its pixel size and in its CRS (then its pixels are the
/// grid's pixels, shifted by whole pixels), within 1e-6 pixel.
bool onGridLattice(const RasterInfo& tile, const WorkingGrid& grid);

} // namespace seasonview
