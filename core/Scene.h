#pragma once
// A scene: a registered leaf-on/leaf-off imagery pair, optional elevation, buildings and ground truth, and the
// local metric frame everything is placed in. Given as a JSON manifest or as CLI flags.
#include "GeoFrame.h"
#include "Heightfield.h"
#include "Raster.h"
#include "Result.h"
#include "Stretch.h"

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace seasonview {

/// Where a scene's files are (absolute or relative to the working directory) and its parameters.
struct SceneSources {
    std::filesystem::path manifest; // empty when given as flags
    std::string name;
    std::filesystem::path leafon, leafoff, elevation, buildings;
    std::filesystem::path truthDeciduous, truthConifer, truthTrees;
    double treeHeightM = 15.0;      // parameters.tree_height_m: canopy height used by the foliage layers
    std::vector<std::string> warnings; // e.g. unknown manifest keys
};

/// Parses a manifest: {"leafon": path, "leafoff": path, "elevation"?: path, "buildings"?: path,
/// "truth"?: {"deciduous"?, "conifer"?, "trees"?}, "parameters"?: {"tree_height_m"?: number}, "name"?: string}.
/// Paths are relative to the manifest's folder. Errors name the manifest and the key.
Result<SceneSources> parseManifest(const std::filesystem::path& manifest);

struct ImageryLayer {
    RasterInfo info; // georef always present
    Stretch stretch;
};

struct Scene {
    SceneSources sources;
    ImageryLayer leafon, leafoff;
    std::optional<Heightfield> elevation; // absent: the scene is flat at height 0
    GeoFrame frame{Crs::geographic(), glm::dvec2(0.0)};
    glm::dvec2 localMin{0.0}, localMax{0.0}; // imagery extent in the local frame, metres
    double gsd = 1.0;                        // leaf-on pixel size along x in local metres
    std::vector<std::string> notes;          // things the user should know (filled DEM holes, ...)

    /// Terrain height (metres) under a local point; 0 for a flat scene.
    double terrainHeight(double x, double y) const {
        return elevation ? elevation->sampleLocal(frame, {x, y}) : 0.0;
    }
    /// Leaf-on pixel coordinates (0..width, 0..height, top-left origin) of a local point.
    glm::dvec2 localToImagePixel(glm::dvec2 local) const {
        return leafon.info.georef->crsToPixel(frame.fromLocal(leafon.info.georef->crs, local));
    }
    /// The local point of leaf-on pixel coordinates (the inverse of localToImagePixel).
    glm::dvec2 imagePixelToLocal(glm::dvec2 px) const {
        return glm::dvec2(frame.toLocal(leafon.info.georef->crs, leafon.info.georef->pixelToCrs(px)));
    }
};

/// Opens the scene's files and checks them: both seasons georeferenced on the same grid (sizes equal, corners
/// within half a pixel), supported CRS, readable DEM with at least one valid sample. Computes (or reads from
/// `cacheDir`) the 16-bit stretch of each season.
Result<Scene> loadScene(const SceneSources& sources, const std::filesystem::path& cacheDir);

} // namespace seasonview
