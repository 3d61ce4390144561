#pragma once
// The options `render`, `bench`, `view` and `demo` share, declared once. Each struct adds one group of options to a
// command (the same names, meanings and help text, listed under the same heading in every command's --help) and
// turns their values into settings; an error is one line that names the option. Defaults may differ per command
// (a command sets the field before calling addTo: the viewer's clipmap is smaller than a still's).
#include "Camera.h"
#include "CanopyDerive.h"
#include "CanopyRendererGL.h"
#include "CityRendererGL.h"
#include "ClipmapCenters.h"
#include "ClipmapTerrainRendererGL.h"
#include "Scene.h"
#include "Segmentation.h"

#include <CLI/CLI.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace seasonview::app {

/// The --help headings of the shared groups, in the order commands list them.
inline constexpr const char* kSceneGroup = "Scene";
inline constexpr const char* kFrameGroup = "Camera and output";
inline constexpr const char* kViewGroup = "View";
inline constexpr const char* kClipmapGroup = "Clipmaps and terrain";
inline constexpr const char* kCanopyGroup = "Canopy view";
inline constexpr const char* kCityGroup = "City";

/// Scene: a manifest or the inputs as flags (each a file, folder, glob or VRT, the flag repeated or given several
/// values for a list), the CRS of inputs that carry none, the working grid, the resampling and the cache. Grid flags
/// given with a manifest override its keys.
struct SceneArgs {
    std::string manifest;
    std::vector<std::string> leafon, leafoff, dem;
    std::string cache;
    std::string crs, gridCrs, extent, extentCrs, extentOf, resampling, stretch, buildings, cityCrs, demEncoding;
    double gridRes = 0.0;
    bool offline = false;
    bool stream = false;
    double webCacheMb = 0.0;
    /// Adds the options to `cmd` (`withDem` false: commands that read no DEM).
    void addTo(CLI::App& cmd, bool withDem = true);
    /// Adds --cache alone (a command that makes its own scene: `demo`).
    void addCacheTo(CLI::App& cmd);
    /// The sources the options name (the manifest's, with the grid flags applied); errors name the flag.
    Result<SceneSources> sources() const;
    Result<Scene> load() const;
    std::filesystem::path cacheDir() const;
};

/// "WxH" -> width, height (1..65536 each; the GL implementation's own limit is checked once a context exists).
Result<std::pair<int, int>> parseSize(const std::string& text);

/// Camera and output: --size, and where the command takes them --camera and --window.
struct FrameArgs {
    std::string size = "1280x720";
    std::string camera; // empty: the command's default camera
    bool window = false;
    struct Parts {
        bool camera = true, window = true;
    };
    /// `sizeHelp`: what the size is of ("Image", "Frame", "Window", "Still").
    void addTo(CLI::App& cmd, const std::string& sizeHelp, Parts parts);
    Result<std::pair<int, int>> frameSize() const;
    /// The --camera string parsed, nullopt when none was given; errors name the option.
    Result<std::optional<CameraSpec>> cameraSpec() const;
};

/// View: what is shown and how the imagery is filtered and shaded.
struct ImageryArgs {
    std::string view = "leafon";
    float blend = 0.5f, swipe = 0.5f, aniso = 8.0f, shade = 0.0f;
    std::string terrain = "on", terrainShading = "auto";
    void addTo(CLI::App& cmd);
    /// The view, blend, swipe, anisotropy, shading, terrain switch and shading path into `imagery`.
    Status apply(ImagerySettings& imagery) const;
};

/// Clipmaps and terrain: the renderer, the level centres, the imagery clipmap's size and levels, the geometry
/// clipmap's grid.
struct ClipmapArgs {
    std::string renderer = "clipmap", centers = "footprint";
    int clipSize = 2048, clipLevels = 0, gridSize = 255;
    /// `withRenderer` false: commands that draw only through clipmaps (`view`).
    void addTo(CLI::App& cmd, bool withRenderer = true);
    Result<CenterPlacement> placement() const;
    Result<bool> referenceRenderer() const;
    /// --clip-size and --grid-size in range.
    Status check() const;
};

/// The `canopy` view: the derived canopy layer's rule and the stacked layers (foliage/CanopyRendererGL.h).
struct CanopyRenderSettings {
    SegmentationParams params;  // method and the ground layer's k
    int layers = 16;            // stacked layers; 0 = off (the ground alone: leaf-off under the crowns)
    bool trunks = true;         // trunks under the crowns (foliage/TrunksGL.h), the layers lifted to the crowns' base
    double crownBaseFraction = 0.35; // with trunks: the crowns' base, fraction of the tree height
    CanopyDrawMode draw = CanopyDrawMode::March; // how the layers are drawn (CanopyRendererGL.h)
    // Derive only the canopy blocks the view's lookups read (CanopyOptions::onDemand); unset: auto.
    std::optional<bool> levelsRead;
    CanopyDerivation derivation = CanopyDerivation::Auto; // where the canopy blocks are derived (--canopy-derive)
};

/// --canopy-layers N|off, --method M, --k K -> canopy settings; errors name the flag.
Result<CanopyRenderSettings> parseCanopyArgs(const std::string& layers, const std::string& method, int k);
/// --trunks on|off -> settings.trunks; errors name the flag.
Status parseTrunksArg(const std::string& value, CanopyRenderSettings& settings);
/// --canopy-draw layers|march -> settings.draw; errors name the flag.
Status parseCanopyDrawArg(const std::string& value, CanopyRenderSettings& settings);
/// --canopy-derive auto|cpu|gpu -> settings.derivation; errors name the flag.
Status parseCanopyDeriveArg(const std::string& value, CanopyRenderSettings& settings);
/// --canopy-levels auto|read|all -> settings.levelsRead (auto: unset); errors name the flag.
Status parseCanopyLevelsArg(const std::string& value, CanopyRenderSettings& settings);
/// --ground-under-canopy / --ground-elsewhere S (leafon|leafoff) -> the canopy view's ground seasons in `imagery`.
Status parseCanopyGround(const std::string& under, const std::string& elsewhere, ImagerySettings& imagery);

/// Canopy view: the segmentation rule of the derived layer, the stacked layers, trunks, the ground's seasons.
struct CanopyArgs {
    std::string layers = "16", method = "default", trunks = "on", draw = "march", levels = "auto", derive = "auto";
    std::string groundUnder = "leafoff", groundElsewhere = "leafon";
    int k = kSegDefaultK;
    void addTo(CLI::App& cmd);
    /// Layers, method, k, trunks and how the layers are drawn.
    Result<CanopyRenderSettings> settings() const;
    /// The ground's seasons under and away from the crowns into `imagery`.
    Status applyGround(ImagerySettings& imagery) const;
};

/// City: the scene's city model and how it is drawn.
struct CityArgs {
    std::string mode = "off"; // atlas | original | flat | blockmap | off
    std::string tree;         // an atlas tree file; empty: the scene's buildings, built into the cache
    double capacityMb = 256.0;
    double tpp = 1.0;
    std::string upload = "auto"; // BC atlases: auto | compressed | decoded
    std::string occlusion = "on"; // atlas mode: occlusion culling on | off
    std::string mapOcclusion = "auto"; // blockmap mode: the tested maps' draws, auto | conditional | readback
    std::string blockMaps;        // blockmap mode: a BlockMap file; empty: built from the tree into the cache
    double blockMapErrorPx = 1.0; // blockmap mode: pixels a map texel may cover where maps replace polygons
    void addTo(CLI::App& cmd);
    /// The renderer settings, nullopt for `off`; errors name the flag.
    Result<std::optional<city::CitySettings>> settings() const;
};

} // namespace seasonview::app
