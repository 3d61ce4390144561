#pragma once
// What `render` and `demo` share: turning CLI scene arguments into a Scene, parsing sizes and cameras, and
// rendering stills with the reference renderer through a headless or windowed context.
#include "Camera.h"
#include "CliOptions.h"
#include "ClipmapCenters.h"
#include "CanopyClipmapGL.h"
#include "CanopyRendererGL.h"
#include "CityRendererGL.h"
#include "ClipmapTerrainRendererGL.h"
#include "ImagePyramid.h"
#include "PairStats.h"
#include "Segmentation.h"
#include "ReferenceRendererGL.h"
#include "Scene.h"
#include "gl/GlContext.h"
#include "gl/RenderTarget.h"

#include <CLI/CLI.hpp>

#include <filesystem>
#include <optional>
#include <memory>
#include <string>
#include <vector>

namespace seasonview::app {

/// The camera looking straight down at the whole scene (default when --camera is not given).
Camera overviewCamera(const Scene& scene, double aspect);

/// An oblique camera `pitchDeg` below the horizon at heading `yawDeg`, looking at the scene centre from
/// `distanceFraction` × the scene diagonal away (kept at least 20 m above the terrain under it).
Camera obliqueCamera(const Scene& scene, double yawDeg, double pitchDeg, double distanceFraction = 0.55);

/// Checks an output image name before any work: extension .png/.tif/.tiff and an existing folder.
Status checkImageOutput(const std::filesystem::path& out);

struct StillRequest {
    Camera camera;
    ImagerySettings imagery;
    std::filesystem::path out;
    std::filesystem::path statsOut; // optional: level statistics JSON (clipmap renderer)
    std::filesystem::path accuracyOut; // optional: PSNR and depth accuracy against the reference renderer (JSON)
    std::filesystem::path cityAccuracyOut; // optional: the city's PSNR against its original textures (JSON)
    city::CityMode cityAccuracyAgainst = city::CityMode::Original; // ... or against another mode's picture (Atlas)
};

enum class RendererKind { Clipmap, Reference };

/// The canopy's draw settings for a scene (tree height, crown base with trunks, the terrain's filtering and shading).
CanopyDrawSettings canopyDrawSettings(const Scene& scene, const CanopyRenderSettings& canopy,
                                      const ImagerySettings& imagery);

struct RenderSettings {
    RendererKind renderer = RendererKind::Clipmap;
    CenterPlacement centers = CenterPlacement::Footprint;
    ClipmapOptions clipmap;
    std::filesystem::path cacheDir; // pyramids (prepared implicitly when missing or stale)
    bool windowed = false;          // a hidden GLFW window instead of EGL (same renderer code)
    float referenceAnisotropy = 16.0f; // reference renderer: the sampler's maximum anisotropy
    GeometryClipmapOptions geometry;   // terrain: the geometry clipmaps' n and elevation streaming
    CanopyRenderSettings canopy;       // the `canopy` view
    std::optional<city::CitySettings> city; // the city model (nullopt: none drawn)
    std::filesystem::path cityTree;         // its atlas tree (prepareCityTree)
    // Stills drawn with K × K samples a pixel, box-filtered down (antialiasing). The city's levels of detail are
    // chosen for the output's pixels (CitySettings::tpp and blockMapErrorPx scaled by K), so an error bound in
    // pixels holds as given; the terrain's are those of the samples.
    int supersample = 1;
};

/// Makes sure both seasons' pyramids are prepared (building them when needed, with a progress bar on a terminal;
/// says so on stdout when it built one), and then the pair's segmentation statistics (preparePairStats). Returns
/// leaf-on, leaf-off.
Result<std::vector<ImagePyramid>> preparePyramids(const Scene& scene, const std::filesystem::path& cacheDir);

/// Preparing one imagery layer: terminalProgress's bar, and for a tile service (web::serviceTileCount) the tiles
/// fetched so far of how many, their megabytes and the time left; note() says after the build what was fetched.
class LayerPrepareProgress {
public:
    LayerPrepareProgress(const char* name, const ImageryLayer& layer, const std::filesystem::path& cacheDir);
    ProgressFn fn() const;
    /// "fetched 9 of 12 tiles (0.26 MB) from the service"; "" for a layer that is no tile service.
    std::string note() const;

private:
    struct State;
    std::shared_ptr<State> m;
};

/// When `message` names a file of a pyramid in the cache (a tile that did not decode), invalidates that pyramid and
/// says so on stdout; returns whether it did (the caller then prepares and runs again, once). A damaged atlas tree
/// in the cache is removed (and said so) to be built again on the next run; false then.
bool rebuildingDamaged(const std::string& message, const std::filesystem::path& cacheDir);

/// For a warped scene (Scene::warped()), its pyramids' level-0 files (leaf-on, leaf-off): what the reference renderer
/// and the segmentation read instead of the seasons' own files. Nothing for a scene read as it is.
std::optional<std::array<std::filesystem::path, 2>> levelZeroOf(const Scene& scene,
                                                               const std::vector<ImagePyramid>& pyramids);

/// The pair's segmentation histograms (foliage/PairStats.h) from the prepared pyramids `pyramids` (leaf-on,
/// leaf-off, as preparePyramids returns them): read from the cache, or computed from both level-0 files and cached
/// (with a progress bar on a terminal; says so on stdout when it computed them). statsFromHistograms() turns them
/// into the equalisation tables and drop threshold of a method. Errors name the file.
Result<SegmentationHistograms> preparePairStats(const Scene& scene, const std::vector<ImagePyramid>& pyramids,
                                                const std::filesystem::path& cacheDir);

/// The recipe of the canopy layer for `options`' parameters (method, k, layers, top k) from the two prepared pyramids
/// `pyramids` (none streamed) and the pair's `stats`: foliage/CanopyPyramid.h's canopyPyramidSource.
PyramidSource canopyLayerSource(const std::vector<ImagePyramid>& pyramids, const CanopyOptions& options,
                                const SegmentationStats& stats);
/// What a canopy layer of `options` is made for, for messages: "default, k 5, 16 layers".
std::string canopyLayerName(const CanopyOptions& options);

/// The canopy layer precomputed for `options`' parameters from the two prepared pyramids `pyramids` and the pair's
/// `stats` (foliage/CanopyPyramid.h), for CanopyOptions::precomputed: with `build` made when the cache has none (with
/// a progress bar on a terminal; says so on stdout when it built it), else the cache's when it has a valid one.
/// nullopt where there is none to use: not prepared (without `build`), or a season streams.
Result<std::optional<ImagePyramid>> canopyPyramid(const std::vector<ImagePyramid>& pyramids,
                                                  const CanopyOptions& options, const SegmentationStats& stats,
                                                  const std::filesystem::path& cacheDir, bool build);

/// Makes sure the DEM's elevation pyramid (terrain/ElevationPyramid.h) is prepared; nullopt for a flat scene.
Result<std::optional<ImagePyramid>> prepareElevation(const Scene& scene, const std::filesystem::path& cacheDir);

/// Level-0 clipmap centres (leaf-on image pixels) of the toroidal levels for a camera.
std::vector<glm::dvec2> clipmapCentres(const Scene& scene, const Camera& camera, int width, int height,
                                       CenterPlacement placement, const ClipmapGeometry& geometry);

/// The clipmap geometry (levels, size, texel size in metres) of a scene's imagery for a clipmap of `size`.
ClipmapGeometry clipmapGeometry(const Scene& scene, const ClipmapLayout& layout);

/// Renders each request with one context and one renderer and writes the images atomically. Prints nothing but
/// what preparing pyramids says; returns the context info.
Result<gl::ContextInfo> renderStills(const Scene& scene, int width, int height, const std::vector<StillRequest>& stills,
                                     const RenderSettings& settings);

/// Writes a render target's colour as an RGB image (PNG or TIFF by extension), atomically.
Status writeRgb(const gl::RenderTarget& target, const std::filesystem::path& out);

/// Prints the scene's warnings and notes to stderr, one line each.
void printSceneNotes(const Scene& scene);

} // namespace seasonview::app
