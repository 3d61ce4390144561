#pragma once
// A scene: a leaf-on/leaf-off imagery pair (each a file or a mosaic, in any CRS and on any grid), optional elevation,
// buildings and ground truth, the working grid both seasons are read on, and the local metric frame everything is
// placed in. Given as a JSON manifest or as CLI flags.
#include "GeoFrame.h"
#include "GridReader.h"
#include "Heightfield.h"
#include "Raster.h"
#include "RasterMosaic.h"
#include "Result.h"
#include "Stretch.h"
#include "WorkingGrid.h"

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>

#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace seasonview {

/// The grid options as the user wrote them (validated by parseGridOptions).
struct GridOptionsText {
    std::string crs;                              // --grid-crs
    std::optional<double> resolution;             // --grid-res
    std::optional<std::array<double, 4>> extent;  // --extent W,S,E,N / xmin,ymin,xmax,ymax
    std::string extentCrs; // --extent-crs: the CRS of --extent, "grid" for the working grid's; empty: degrees
                           // (WGS 84 longitude, latitude) when the four numbers read as such, else the grid's CRS
    std::string extentOf;  // --extent-of leafon|leafoff|dem: the extent is that input's footprint
};

/// Where a scene's files are (absolute or relative to the working directory) and its parameters.
struct SceneSources {
    std::filesystem::path manifest; // empty when given as flags
    std::string name;
    SourceList leafon, leafoff, elevation; // each: files, folders, globs or VRTs
    std::filesystem::path buildings;
    std::string buildingsCrs;       // --city-crs / "buildings_crs": the CRS of a model that names none (OBJ); empty:
                                    // an OBJ is in the scene's local frame (what `synth` writes)
    std::filesystem::path truthDeciduous, truthConifer, truthTrees;
    double treeHeightM = 15.0;      // parameters.tree_height_m: canopy height used by the foliage layers
    std::string crs;                // --crs / "crs": the CRS of rasters that carry none (PROJ user input)
    GridOptionsText grid;           // --grid-crs, --grid-res, --extent, --extent-crs, --extent-of / "grid_crs",
                                    // "grid_res", "extent", "extent_crs", "extent_of"
    std::string elevationEncoding;  // --dem-encoding / "elevation_encoding": value|terrarium|mapbox (HeightEncoding)
    bool offline = false;           // --offline / "offline": web sources from the disk cache only (WebSource.h)
    bool stream = false;            // --stream / "stream": seasons from tile services are streamed into the clipmaps
                                    // level by level instead of prepared at full resolution (StreamedPyramid.h)
    double webCacheMb = 0.0;       // --web-cache-mb / "web_cache_mb": the tile services' disk cache bound in MiB
                                    // (0: web::kDefaultWebCacheMb)
    std::string resampling = "auto"; // --resampling / "resampling"
    std::string stretch = "auto";    // --stretch / "stretch": StretchMode
    std::vector<std::string> warnings; // e.g. unknown manifest keys
};

/// Parses a manifest: {"leafon": P, "leafoff": P, "elevation"?: P, "buildings"?: path,
/// "truth"?: {"deciduous"?, "conifer"?, "trees"?}, "parameters"?: {"tree_height_m"?: number}, "name"?: string,
/// "crs"?: string, "grid_crs"?: string, "grid_res"?: number, "extent"?: [W, S, E, N], "extent_crs"?: string,
/// "extent_of"?: "leafon"|"leafoff"|"dem", "offline"?: bool, "stream"?: bool, "web_cache_mb"?: number, "elevation_encoding"?: string,
/// "resampling"?: string, "stretch"?: string, "buildings_crs"?: string}, where P is a path (a file, a folder, a glob, a VRT) or a list of them. Paths are relative
/// to the manifest's folder. Errors name the manifest and the key.
Result<SceneSources> parseManifest(const std::filesystem::path& manifest);

struct ImageryLayer {
    RasterMosaic source; // the season as delivered
    /// The season as it is read: on the working grid (its size and georef), 3 channels of the source's sample type;
    /// `path` the source file when `direct`, else empty.
    RasterInfo info;
    Stretch stretch;
    /// One file that is the working grid and marks no pixel as nodata: read as it is (BandReader), never warped.
    bool direct = false;
    Resampling resampling = Resampling::Auto; // how it is warped onto the grid
    /// The working grid (info's georef and size).
    WorkingGrid grid() const { return WorkingGrid{*info.georef, info.width, info.height}; }
};

struct Scene {
    SceneSources sources;
    WorkingGrid grid;                       // both seasons are read on it; outputs are written on it
    Resampling resampling = Resampling::Auto;
    ImageryLayer leafon, leafoff;
    std::optional<Heightfield> elevation; // absent: the scene is flat at height 0
    GeoFrame frame{Crs::geographic(), glm::dvec2(0.0)};
    glm::dvec2 localMin{0.0}, localMax{0.0}; // imagery extent in the local frame, metres
    double gsd = 1.0;                        // grid pixel size along x in local metres
    std::vector<std::string> notes;          // things the user should know (filled DEM holes, warped seasons, ...)

    /// Terrain height (metres) under a local point; 0 for a flat scene.
    double terrainHeight(double x, double y) const {
        return elevation ? elevation->sampleLocal(frame, {x, y}) : 0.0;
    }
    /// Grid pixel coordinates (0..width, 0..height, top-left origin) of a local point.
    glm::dvec2 localToImagePixel(glm::dvec2 local) const {
        return grid.georef.crsToPixel(frame.fromLocal(grid.georef.crs, local));
    }
    /// The local point of grid pixel coordinates (the inverse of localToImagePixel).
    glm::dvec2 imagePixelToLocal(glm::dvec2 px) const {
        return glm::dvec2(frame.toLocal(grid.georef.crs, grid.georef.pixelToCrs(px)));
    }
    /// Whether either season is warped (read from its prepared pyramid rather than from its file).
    bool warped() const { return !leafon.direct || !leafoff.direct; }
};

/// Opens the scene's inputs and checks them: each season a mosaic of georeferenced rasters (8- or 16-bit, at least
/// 3 bands) in any CRS; the working grid chosen from both (chooseWorkingGrid: they must overlap); the DEM (any CRS,
/// mosaics too) read over the grid's area with at least one valid sample. Computes (or reads from `cacheDir`) each
/// season's 16-bit stretch.
Result<Scene> loadScene(const SceneSources& sources, const std::filesystem::path& cacheDir);

/// Whether a season or DEM input is a tile service (an XYZ/TMS template or a WMTS layer).
bool isTileService(const SourceList& s);

/// The scene's season `role` ("leafon" or "leafoff") read from its tile service on `grid` (the working grid, or a
/// coarser one on its lattice): the service described over the grid's area at the grid's pixel size (the zoom that
/// matches it), opened and placed on `grid` as loadScene places the full-resolution season, with the scene's
/// stretch. What streaming reads each clip level through, and what the resident coarse levels are prepared from.
/// `maxConnections`: the reader's share of the connections to the service (web::ServiceOptions).
Result<ImageryLayer> serviceLayerOnGrid(const Scene& scene, const std::string& role, const WorkingGrid& grid,
                                        const std::filesystem::path& cacheDir, int maxConnections = 4);

/// One season opened as loadScene opens it (a mosaic of 8- or 16-bit rasters of 3 or more bands, its stretch), placed
/// on `grid` (default: its first file's own grid). For tools and tests that need one layer without a pair.
Result<ImageryLayer> openImageryLayer(const SourceList& sources, const std::string& role,
                                      const std::filesystem::path& cacheDir, const WorkingGrid* grid = nullptr,
                                      const std::optional<Crs>& assumedCrs = {},
                                      Resampling resampling = Resampling::Auto,
                                      StretchMode stretch = StretchMode::Auto);

/// The grid options of `sources` parsed: errors name the flag (--grid-crs, --grid-res, --extent, --extent-crs, --crs).
/// --extent-of is resolved by loadScene (it needs the inputs opened).
Result<GridOptions> parseGridOptions(const SceneSources& sources);

} // namespace seasonview
