#pragma once
// The viewer's scene on the GPU (clipmaps, terrain, canopy, trunks, city: made as `render` and `bench` make them) and
// the settings its panel, keys and scripts change.
#include "CanopyClipmapGL.h"
#include "CanopyRendererGL.h"
#include "CityRendererGL.h"
#include "ClipmapCenters.h"
#include "ClipmapTerrainRendererGL.h"
#include "ImagePyramid.h"
#include "PairStats.h"
#include "Scene.h"
#include "SeasonCoverage.h"
#include "Segmentation.h"
#include "TrunksGL.h"
#include "gl/RenderTarget.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace seasonview::app {

/// What the panel edits (and `set` events in scripts).
struct ViewerSettings {
    // What is shown and how (view, blend, swipe and shading change in the panel; filtering, shading path, terrain on
    // or off and the canopy ground's seasons as the command line set them).
    ImagerySettings imagery;
    int layers = 16; // 0: off
    bool trunks = true;
    bool marchLayers = true; // CanopyDrawMode::March (false: every layer rasterised)
    std::optional<bool> canopyLevelsRead; // derive only the canopy blocks read (CanopyOptions::onDemand; --canopy-levels)
    CanopyDerivation canopyDerivation = CanopyDerivation::Auto; // --canopy-derive
    CenterPlacement centers = CenterPlacement::Footprint;
    SegmentationParams params{SegmentationMethod::Default, kSegDefaultK};
    bool panel = true;
    int coverageEvery = 30; // frames between coverage measurements (0: never)
    bool city = true;       // the city model, when the viewer was started with one (key B)
    float cityTpp = 1.0f;   // its pixels per texel
    bool cityBlockMaps = true; // started with --city blockmap: BlockMaps far (key G; off: the atlas tree everywhere)
};

/// Applies a script's `set` event or a panel change given by name (view, blend, swipe, shading, layers, city,
/// city_tpp, city_blockmaps, trunks, canopy_draw, centers, method, k, panel); false and `err` for an unknown name or value.
bool applySetting(ViewerSettings& s, const std::string& name, const nlohmann::json& v, std::string& err);

/// The scene on the GPU: clipmaps, terrain, canopy, trunks and city, as `render` and `bench` make them.
struct LiveScene {
    const Scene* scene = nullptr;
    std::vector<ImagePyramid> pyramids;
    std::optional<SeasonCoverageProbe> coverage; // which season has data under the cursor (HUD)
    std::optional<ImagePyramid> elevation;
    std::optional<SegmentationHistograms> histograms;
    std::filesystem::path cache;
    std::unique_ptr<ClipmapGL> clip;
    std::unique_ptr<ClipmapTerrainRendererGL> terrain;
    std::unique_ptr<CanopyClipmapGL> canopy;
    std::unique_ptr<CanopyRendererGL> canopyRenderer;
    std::unique_ptr<TrunksGL> trunks;
    SegmentationParams canopyParams{};
    int canopyLayers = -1;
    bool canopyTrunks = false;
    ClipmapFrameStats lastLoad;
    std::int64_t texelsTotal = 0;
    bool damagedReported = false, cityDamageReported = false;
    std::int64_t streamErrorsReported = 0; // streamed tiles that failed, as last said on stderr
    std::string lastStreamErrorReported;
    std::unique_ptr<city::CityRendererGL> city;
    city::CityFrameStats cityStats;

    /// (Re)makes the canopy when its rule, layer count or trunks changed (the derived layer is recomputed).
    Status ensureCanopy(const ViewerSettings& s);
    /// One frame into `target`. `complete`: wait for every texel the view needs (screenshots).
    GeometryFrameStats draw(const Camera& cam, const ViewerSettings& s, const gl::RenderTarget& target, bool complete);
    /// Once each: a cache tile of the imagery or the elevation that did not read (drawn from coarser levels) said on
    /// stderr, its pyramid marked to be rebuilt on the next start; a city block that did not read or decode.
    void reportDamage();
    std::int64_t residentBytes() const { return clip->residentBytes() + (canopy ? canopy->residentBytes() : 0); }
};

} // namespace seasonview::app
