#include "CliOptions.h"

#include "Stretch.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <sstream>

namespace seasonview::app {

namespace {

// Puts the options added to `cmd` since it had `first` under the --help heading `group`.
void groupFrom(CLI::App& cmd, size_t first, const char* group) {
    const std::vector<CLI::Option*> all = cmd.get_options();
    for (size_t i = first; i < all.size(); ++i) all[i]->group(group);
}

SourceList listOf(const std::vector<std::string>& values) {
    SourceList l;
    for (const std::string& v : values) l.items.emplace_back(v);
    return l;
}

} // namespace

void SceneArgs::addTo(CLI::App& cmd, bool withDem) {
    const size_t first = cmd.get_options().size();
    cmd.add_option("scene", manifest, "Scene manifest (scene.json); or give --leafon/--leafoff");
    cmd.add_option("--leafon", leafon,
                   "Leaf-on (summer) imagery, 8- or 16-bit RGB(A) in any format and CRS GDAL reads: a file, a folder "
                   "of tiles, a glob, a VRT (several for a mosaic), an http(s):// URL read by range requests (a "
                   "Cloud-Optimized GeoTIFF), an XYZ tile service's URL template with {z}, {x} and {y} ({-y}: TMS "
                   "rows), or a WMTS capabilities URL with ?layer=NAME (&tilematrixset=ID, &style=ID); a service is "
                   "read over --extent, else the other season's footprint, at --grid-res, else the other season's "
                   "pixel size")
        ->expected(1, -1);
    cmd.add_option("--leafoff", leafoff,
                   "Leaf-off (winter) imagery, as --leafon; any grid, resolution and CRS (warped onto the working "
                   "grid)")
        ->expected(1, -1);
    if (withDem) {
        cmd.add_option("--dem", dem,
                       "Elevation (metres or feet) in any format and CRS: a file, folder, glob or VRT of tiles, "
                       "or a URL as --leafon (a tile service with --dem-encoding); flat without")
            ->expected(1, -1);
        cmd.add_option("--dem-encoding", demEncoding,
                       "How the DEM's samples hold heights: value (default), terrarium or mapbox (Terrain-RGB): "
                       "8-bit RGB tiles of an elevation tile service")
            ->check(CLI::IsMember({"value", "terrarium", "mapbox"}));
        cmd.add_option("--buildings", buildings, "City model (CityGML or OBJ) for --city, when no manifest names one");
        cmd.add_option("--city-crs", cityCrs,
                       "CRS of a city model that names none (an OBJ in real coordinates), e.g. EPSG:25833; without it "
                       "an OBJ is in the scene's local frame");
    }
    cmd.add_option("--crs", crs, "CRS of inputs that carry none, e.g. EPSG:2154 (any EPSG code, URN, WKT or PROJ string)");
    cmd.add_option("--grid-crs", gridCrs,
                   "Working grid's CRS (default: the leaf-on's when projected, else its UTM zone)");
    cmd.add_option("--grid-res", gridRes,
                   "Working grid's pixel size in its CRS's units (default: the finest season's)");
    cmd.add_option("--extent", extent,
                   "Scene's extent W,S,E,N: degrees (WGS 84 longitudes, latitudes) when the numbers read as such, "
                   "else in the working grid's CRS (default: the union of both seasons)");
    cmd.add_option("--extent-crs", extentCrs,
                   "The CRS --extent is given in (any EPSG code, URN, WKT or PROJ string; 'grid': the working grid's)");
    cmd.add_option("--extent-of", extentOf,
                   "Scene's extent: the footprint of one input, leafon|leafoff|dem")
        ->check(CLI::IsMember({"leafon", "leafoff", "dem"}));
    cmd.add_flag("--offline", offline,
                 "Tile services from the disk cache only (no request; tiles never fetched are no data)");
    cmd.add_flag("--stream", stream,
                 "Seasons from tile services streamed into the clipmaps as the view needs them (each clip level at "
                 "its zoom) instead of prepared at full resolution first");
    cmd.add_option("--web-cache-mb", webCacheMb,
                   "Bound of the tile services' disk cache in MiB (least recently fetched tiles go; default 1024)")
        ->check(CLI::PositiveNumber);
    cmd.add_option("--resampling", resampling,
                   "How seasons are warped onto the working grid: auto|near|bilinear|cubic|average|lanczos (auto: "
                   "near on the grid's lattice, average where a season is 1.5x finer, else bilinear)");
    cmd.add_option("--stretch", stretch,
                   "Display (and segmentation) colour: auto (16-bit through a per-band 0.5-99.5 % stretch, 8-bit as "
                   "it is), percentile (the stretch for 8-bit too: 8-bit radiometric data such as scaled reflectance), "
                   "none");
    groupFrom(cmd, first, kSceneGroup);
    addCacheTo(cmd);
}

void SceneArgs::addCacheTo(CLI::App& cmd) {
    cmd.add_option("--cache", cache, "Cache folder (default $SEASONVIEW_CACHE or ~/.cache/seasonview)")->group(kSceneGroup);
}

std::filesystem::path SceneArgs::cacheDir() const {
    return cache.empty() ? defaultCacheDir() : std::filesystem::path(cache);
}

Result<SceneSources> SceneArgs::sources() const {
    SceneSources src;
    if (!manifest.empty()) {
        if (!leafon.empty() || !leafoff.empty() || !dem.empty())
            return Error{"scene: give either a manifest or --leafon/--leafoff/--dem, not both"};
        auto parsed = parseManifest(manifest);
        if (!parsed) return parsed.error();
        src = std::move(*parsed);
    } else {
        if (leafon.empty() || leafoff.empty())
            return Error{"scene: give a manifest (scene.json) or both --leafon and --leafoff"};
        src.leafon = listOf(leafon);
        src.leafoff = listOf(leafoff);
        src.elevation = listOf(dem);
        src.name = std::filesystem::path(leafon.front()).stem().string();
    }
    if (!crs.empty()) src.crs = crs;
    if (!gridCrs.empty()) src.grid.crs = gridCrs;
    if (gridRes != 0.0) {
        if (!(gridRes > 0.0) || !std::isfinite(gridRes))
            return Error{"--grid-res: a positive number of grid CRS units per pixel expected"};
        src.grid.resolution = gridRes;
    }
    if (!extent.empty()) {
        std::array<double, 4> e{};
        std::istringstream in(extent);
        char comma = 0;
        if (!(in >> e[0] >> comma >> e[1] >> comma >> e[2] >> comma >> e[3]) || !(in >> std::ws).eof())
            return Error{"--extent '" + extent + "': expected W,S,E,N (degrees, or in --extent-crs)"};
        src.grid.extent = e;
        src.grid.extentOf.clear(); // the flags win over the manifest's keys
        src.grid.extentCrs = extentCrs;
    } else if (!extentCrs.empty()) {
        src.grid.extentCrs = extentCrs;
    }
    if (!extentOf.empty()) {
        if (!extentCrs.empty()) return Error{"--extent-crs: the CRS of --extent, not of --extent-of"};
        src.grid.extentOf = extentOf;
        if (extent.empty()) src.grid.extent.reset(), src.grid.extentCrs.clear();
    }
    if (!demEncoding.empty()) src.elevationEncoding = demEncoding;
    if (offline) src.offline = true;
    if (stream) src.stream = true;
    if (webCacheMb > 0) src.webCacheMb = webCacheMb;
    if (!resampling.empty()) src.resampling = resampling;
    if (!buildings.empty()) src.buildings = buildings;
    if (!cityCrs.empty()) src.buildingsCrs = cityCrs;
    if (!stretch.empty()) src.stretch = stretch;
    return src;
}

Result<Scene> SceneArgs::load() const {
    auto src = sources();
    if (!src) return src.error();
    return loadScene(*src, cacheDir());
}

Result<std::pair<int, int>> parseSize(const std::string& text) {
    const size_t x = text.find_first_of("xX");
    // The GL implementation's own limit (ContextInfo::maxFramebufferSide) is checked once a context exists.
    auto bad = [&] { return Error{"size '" + text + "': expected WxH, e.g. 1920x1080 (each 1..65536)"}; };
    if (x == std::string::npos) return bad();
    int w = 0, h = 0;
    auto r1 = std::from_chars(text.data(), text.data() + x, w);
    auto r2 = std::from_chars(text.data() + x + 1, text.data() + text.size(), h);
    if (r1.ec != std::errc() || r1.ptr != text.data() + x || r2.ec != std::errc() ||
        r2.ptr != text.data() + text.size() || w < 1 || h < 1 || w > 65536 || h > 65536)
        return bad();
    return std::pair{w, h};
}

void FrameArgs::addTo(CLI::App& cmd, const std::string& sizeHelp, Parts parts) {
    const size_t first = cmd.get_options().size();
    if (parts.camera)
        cmd.add_option("--camera", camera,
                       "X,Y,Z,YAW,PITCH[,FOV]: local metres (x east, y north, z up; Z may be +H = H m above the "
                       "terrain), yaw = heading in degrees (0 north, clockwise), pitch in degrees (-90 down), fov "
                       "vertical degrees (default 60). Default: straight down over the whole scene");
    cmd.add_option("--size", size, sizeHelp + " size WxH")->capture_default_str();
    if (parts.window) cmd.add_flag("--window", window, "Render through a hidden GLFW window instead of headless EGL");
    groupFrom(cmd, first, kFrameGroup);
}

Result<std::pair<int, int>> FrameArgs::frameSize() const { return parseSize(size); }

Result<std::optional<CameraSpec>> FrameArgs::cameraSpec() const {
    if (camera.empty()) return std::optional<CameraSpec>();
    auto parsed = parseCamera(camera);
    if (!parsed) return parsed.error();
    return std::optional<CameraSpec>(*parsed);
}

void ImageryArgs::addTo(CLI::App& cmd) {
    const size_t first = cmd.get_options().size();
    cmd.add_option("--view", view, "What to show: leafon|leafoff|blend|swipe|lod|wireframe|levels|relief|canopy")
        ->capture_default_str();
    cmd.add_option("--blend", blend, "blend view: 0 = leaf-on .. 1 = leaf-off")->capture_default_str();
    cmd.add_option("--swipe", swipe, "swipe view: fraction of the width showing leaf-on")->capture_default_str();
    cmd.add_option("--aniso", aniso,
                   "Maximum anisotropy, 1..16 (1 = isotropic): probes per pixel of the clipmap's footprint filter; "
                   "the reference renderer's sampler anisotropy")
        ->check(CLI::Range(1.0f, kMaxAnisotropy))
        ->capture_default_str();
    cmd.add_option("--shade", shade, "Lambert shading of the relief from the elevation's normals, 0..1")
        ->check(CLI::Range(0.0f, 1.0f))
        ->capture_default_str();
    cmd.add_option("--terrain-shading", terrainShading,
                   "How the terrain's fragments are shaded: deferred (a geometry pass, then each pixel once), "
                   "forward (as rasterised), or auto: deferred on a software rasteriser (llvmpipe), forward on a GPU; "
                   "the same pixels")
        ->check(CLI::IsMember({"auto", "forward", "deferred"}))
        ->capture_default_str();
    cmd.add_option("--terrain", terrain,
                   "on: the terrain drawn; off: only the city (its facades and roofs; needs --city), as the "
                   "atlas-tree paper timed it")
        ->check(CLI::IsMember({"on", "off"}))
        ->capture_default_str();
    groupFrom(cmd, first, kViewGroup);
}

Status ImageryArgs::apply(ImagerySettings& imagery) const {
    const auto v = parseImageryView(view);
    if (!v) return Error{"--view '" + view + "': expected leafon|leafoff|blend|swipe|lod|wireframe|levels|relief|canopy"};
    imagery.view = *v;
    imagery.blend = blend;
    imagery.swipe = swipe;
    if (!(aniso >= 1.0f && aniso <= kMaxAnisotropy)) return Error{"--aniso: expected 1..16"};
    imagery.anisotropy = aniso;
    imagery.shading = shade;
    if (terrain != "on" && terrain != "off") return Error{"--terrain '" + terrain + "': expected on|off"};
    imagery.terrain = terrain == "on";
    const auto path = parseTerrainShading(terrainShading);
    if (!path) return Error{"--terrain-shading '" + terrainShading + "': expected auto|forward|deferred"};
    imagery.path = *path;
    return Ok{};
}

void ClipmapArgs::addTo(CLI::App& cmd, bool withRenderer) {
    const size_t first = cmd.get_options().size();
    if (withRenderer)
        cmd.add_option("--renderer", renderer,
                       "Renderer: clipmap (streamed texture clipmaps) | reference (brute force, full-resolution "
                       "textures)")
            ->capture_default_str();
    cmd.add_option("--centers", centers, "Clipmap level centres: " + placementNames())->capture_default_str();
    cmd.add_option("--clip-size", clipSize, "Clipmap level size N, texels (256..4096, multiple of 64)")
        ->capture_default_str();
    cmd.add_option("--clip-levels", clipLevels,
                   "Toroidal clipmap levels allocated at least (0 = as the image needs; fixed = same memory for "
                   "every image)")
        ->check(CLI::Range(0, 16))
        ->capture_default_str();
    cmd.add_option("--grid-size", gridSize, "Geometry clipmap: vertices per level side n = 2^k - 1 (31..1023)")
        ->capture_default_str();
    groupFrom(cmd, first, kClipmapGroup);
}

Result<CenterPlacement> ClipmapArgs::placement() const {
    const auto c = parsePlacement(centers);
    if (!c) return Error{"--centers '" + centers + "': expected " + placementNames()};
    return *c;
}

Result<bool> ClipmapArgs::referenceRenderer() const {
    if (renderer != "clipmap" && renderer != "reference")
        return Error{"--renderer '" + renderer + "': expected clipmap|reference"};
    return renderer == "reference";
}

Status ClipmapArgs::check() const {
    if (gridSize < 31 || gridSize > 1023 || ((gridSize + 1) & gridSize) != 0)
        return Error{"--grid-size " + std::to_string(gridSize) + ": expected 2^k - 1 in 31..1023"};
    if (clipSize < 256 || clipSize > 4096 || clipSize % 64 != 0)
        return Error{"--clip-size " + std::to_string(clipSize) + ": expected 256..4096, a multiple of 64"};
    return Ok{};
}
Result<CanopyRenderSettings> parseCanopyArgs(const std::string& layers, const std::string& method, int k) {
    CanopyRenderSettings c;
    if (layers == "off") {
        c.layers = 0;
    } else {
        int n = 0;
        const auto [ptr, ec] = std::from_chars(layers.data(), layers.data() + layers.size(), n);
        if (ec != std::errc() || ptr != layers.data() + layers.size() || n < 1 || n > 32)
            return Error{"--canopy-layers '" + layers + "': expected 1..32 or off"};
        c.layers = n;
    }
    const auto m = parseSegmentationMethod(method);
    if (!m) return Error{"--method '" + method + "': expected pixel|neighborhood|equalized|default"};
    c.params.method = *m;
    if (k < 1 || k > kSegMaxK || k % 2 == 0)
        return Error{"--k " + std::to_string(k) + ": expected an odd number in 1.." + std::to_string(kSegMaxK)};
    c.params.k = k;
    return c;
}

Status parseTrunksArg(const std::string& value, CanopyRenderSettings& settings) {
    if (value != "on" && value != "off") return Error{"--trunks '" + value + "': expected on|off"};
    settings.trunks = value == "on";
    return Ok{};
}

Status parseCanopyLevelsArg(const std::string& value, CanopyRenderSettings& settings) {
    if (value != "read" && value != "all" && value != "auto")
        return Error{"--canopy-levels '" + value + "': expected auto|read|all"};
    settings.levelsRead = value == "auto" ? std::nullopt : std::optional<bool>(value == "read");
    return Ok{};
}

Status parseCanopyDeriveArg(const std::string& value, CanopyRenderSettings& settings) {
    if (value == "auto") settings.derivation = CanopyDerivation::Auto;
    else if (value == "cpu") settings.derivation = CanopyDerivation::Cpu;
    else if (value == "gpu") settings.derivation = CanopyDerivation::Gpu;
    else return Error{"--canopy-derive '" + value + "': expected auto|cpu|gpu"};
    return Ok{};
}

Status parseCanopyDrawArg(const std::string& value, CanopyRenderSettings& settings) {
    if (value != "layers" && value != "march") return Error{"--canopy-draw '" + value + "': expected layers|march"};
    settings.draw = value == "layers" ? CanopyDrawMode::Layers : CanopyDrawMode::March;
    return Ok{};
}

Status parseCanopyGround(const std::string& under, const std::string& elsewhere, ImagerySettings& imagery) {
    auto season = [](const std::string& flag, const std::string& v) -> Result<int> {
        if (v == "leafon") return 0;
        if (v == "leafoff") return 1;
        return Error{flag + " '" + v + "': expected leafon|leafoff"};
    };
    auto u = season("--ground-under-canopy", under);
    if (!u) return u.error();
    auto e = season("--ground-elsewhere", elsewhere);
    if (!e) return e.error();
    imagery.groundUnderCanopy = *u;
    imagery.groundElsewhere = *e;
    return Ok{};
}

void CanopyArgs::addTo(CLI::App& cmd) {
    const size_t first = cmd.get_options().size();
    cmd.add_option("--canopy-layers", layers,
                   "canopy view: stacked canopy layers, 1..32, or off (the ground alone: leaf-off under the crowns)")
        ->capture_default_str();
    cmd.add_option("--method", method,
                   "canopy view: segmentation method of the canopy layer, pixel|neighborhood|equalized|default")
        ->capture_default_str();
    cmd.add_option("--k", k, "canopy view: neighbourhood size of the ground layer (odd, 1..15)")->capture_default_str();
    cmd.add_option("--trunks", trunks,
                   "canopy view: trunks at the crown centres found in the canopy layer, the crowns lifted to their "
                   "base; on|off")
        ->capture_default_str();
    cmd.add_option("--canopy-draw", draw,
                   "canopy view: how the stacked layers are drawn: march (the top layer rasterised, each pixel's ray "
                   "intersected with the layers below) or layers (every layer rasterised, §4.2 as written); layers|march")
        ->capture_default_str();
    cmd.add_option("--canopy-levels", levels,
                   "canopy view (view, bench): which blocks of the canopy layer are derived as they arrive: read (on "
                   "levels finer than the trunks' search level, only those the view's canopy lookups have read; a "
                   "lookup falls back to the next coarser level until its block is derived), all, or auto (read where "
                   "the blocks are derived on the GPU, all on the CPU); stills derive everything; auto|read|all")
        ->capture_default_str();
    cmd.add_option("--canopy-derive", derive,
                   "canopy view: where the canopy layer's blocks are derived: cpu (the block loader's workers, as "
                   "blocks are read; the render thread uploads a byte per texel), gpu (a compute shader, once a block "
                   "and its neighbours are uploaded; the same values) or auto (cpu, gpu when the imagery streams from "
                   "a service); auto|cpu|gpu")
        ->capture_default_str();
    cmd.add_option("--ground-under-canopy", groundUnder,
                   "canopy view: season of the ground under the crowns (seen where layers are off), leafon|leafoff")
        ->capture_default_str();
    cmd.add_option("--ground-elsewhere", groundElsewhere,
                   "canopy view: season of the ground away from the crowns, leafon|leafoff")
        ->capture_default_str();
    groupFrom(cmd, first, kCanopyGroup);
}

Result<CanopyRenderSettings> CanopyArgs::settings() const {
    auto c = parseCanopyArgs(layers, method, k);
    if (!c) return c.error();
    if (auto st = parseTrunksArg(trunks, *c); !st) return st.error();
    if (auto st = parseCanopyDrawArg(draw, *c); !st) return st.error();
    if (auto st = parseCanopyLevelsArg(levels, *c); !st) return st.error();
    if (auto st = parseCanopyDeriveArg(derive, *c); !st) return st.error();
    return c;
}

Status CanopyArgs::applyGround(ImagerySettings& imagery) const {
    return parseCanopyGround(groundUnder, groundElsewhere, imagery);
}
void CityArgs::addTo(CLI::App& cmd) {
    const size_t first = cmd.get_options().size();
    cmd.add_option("--city", mode,
                   "City model (the scene's `buildings`): atlas (texture-atlas tree), original (each original texture "
                   "bound per draw), flat (one dummy texture, the upper bound), blockmap (the atlas tree near, "
                   "ray-cast BlockMaps far), off")
        ->check(CLI::IsMember({"atlas", "original", "flat", "blockmap", "off"}))
        ->capture_default_str();
    cmd.add_option("--city-tree", tree, "Atlas tree file to draw (default: built from the scene's buildings into the cache)");
    cmd.add_option("--city-capacity", capacityMb, "Resident atlases and original textures, MB")->capture_default_str();
    cmd.add_option("--city-tpp", tpp, "City: pixels per texel allowed (larger: coarser atlases)")->capture_default_str();
    cmd.add_option("--city-upload", upload,
                   "City: BC atlases uploaded compressed, decoded (RGB8), or auto (decoded on software rasterisers)")
        ->check(CLI::IsMember({"auto", "compressed", "decoded"}))
        ->capture_default_str();
    cmd.add_option("--city-occlusion", occlusion,
                   "City, atlas mode: skip nodes hidden behind what is drawn (occlusion queries on node boxes)")
        ->check(CLI::IsMember({"on", "off"}))
        ->capture_default_str();
    cmd.add_option("--city-map-occlusion", mapOcclusion,
                   "City, blockmap mode: the maps tested for occlusion drawn under conditional rendering, after "
                   "reading the answers in one instanced draw, or auto (readback on software rasterisers)")
        ->check(CLI::IsMember({"auto", "conditional", "readback"}))
        ->capture_default_str();
    cmd.add_option("--city-blockmaps", blockMaps,
                   "City, blockmap mode: BlockMap file to draw (default: built from the atlas tree into the cache)");
    cmd.add_option("--city-blockmap-error", blockMapErrorPx,
                   "City, blockmap mode: pixels one BlockMap texel may cover where maps are drawn instead of polygons")
        ->capture_default_str();
    groupFrom(cmd, first, kCityGroup);
}

Result<std::optional<city::CitySettings>> CityArgs::settings() const {
    if (mode == "off") return std::optional<city::CitySettings>();
    if (!(capacityMb >= 1.0)) return Error{"--city-capacity must be at least 1 MB"};
    if (!(tpp > 0.0)) return Error{"--city-tpp must be positive"};
    city::CitySettings s;
    s.mode = *city::parseCityMode(mode);
    s.capacityBytes = std::uint64_t(capacityMb * 1048576.0);
    s.tpp = tpp;
    s.upload = city::parseAtlasUpload(upload).value_or(city::AtlasUpload::Auto);
    s.occlusion = occlusion != "off";
    s.mapOcclusion = city::parseMapOcclusion(mapOcclusion).value_or(city::MapOcclusion::Auto);
    if (!(blockMapErrorPx > 0.0) || !std::isfinite(blockMapErrorPx)) return Error{"--city-blockmap-error must be positive"};
    s.blockMaps = blockMaps;
    s.blockMapErrorPx = blockMapErrorPx;
    return std::optional<city::CitySettings>(s);
}

} // namespace seasonview::app
