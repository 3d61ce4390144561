#include "Scene.h"

#include "JsonFile.h"
#include "WebSource.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <limits>
#include <cmath>
#include <fstream>
#include <span>
#include <sstream>

namespace seasonview {

namespace {

using nlohmann::json;

} // namespace

namespace {

Result<SceneSources> manifestFromJson(const json& j, const std::filesystem::path& manifest);

} // namespace

Result<SceneSources> parseManifest(const std::filesystem::path& manifest) {
    const std::string name = manifest.string();
    std::error_code ec;
    if (std::filesystem::is_directory(manifest, ec))
        return fileError(name, "is a directory; give the scene's manifest (scene.json)");
    auto j = readJsonFile(manifest, "manifest");
    if (!j) return j.error();
    try {
        return manifestFromJson(*j, manifest);
    } catch (const json::exception& e) { // a value of an unexpected type that a check below missed
        return fileError(name, "manifest: " + firstLine(e.what()));
    }
}

namespace {

Result<SceneSources> manifestFromJson(const json& j, const std::filesystem::path& manifest) {
    const std::string name = manifest.string();
    if (!j.is_object()) return fileError(name, "manifest must be a JSON object");

    SceneSources s;
    s.manifest = manifest;
    const std::filesystem::path base = manifest.parent_path();
    auto resolve = [&](const std::string& relative) {
        const std::filesystem::path p = relative;
        return p.is_absolute() || web::isUrl(relative) ? p : base / p; // a URL stays one (WebSource.h)
    };
    auto path = [&](const json& obj, const char* key, bool required, std::filesystem::path& out,
                    const std::string& prefix) -> Status {
        auto it = obj.find(key);
        if (it == obj.end() || it->is_null()) {
            if (required) return fileError(name, "missing required key '" + prefix + key + "'");
            return Ok{};
        }
        if (!it->is_string() || it->get<std::string>().empty())
            return fileError(name, "'" + prefix + key + "' must be a non-empty string (a path relative to the manifest)");
        out = resolve(it->get<std::string>());
        return Ok{};
    };
    // A season or DEM: a path (file, folder, glob, VRT) or a list of them.
    auto sources = [&](const char* key, bool required, SourceList& out) -> Status {
        auto it = j.find(key);
        if (it == j.end() || it->is_null()) {
            if (required) return fileError(name, std::string("missing required key '") + key + "'");
            return Ok{};
        }
        const std::string what = std::string("'") + key +
                                 "' must be a non-empty string or list of strings (files, folders, globs or VRTs "
                                 "relative to the manifest)";
        if (it->is_string()) {
            if (it->get<std::string>().empty()) return fileError(name, what);
            out = SourceList(resolve(it->get<std::string>()));
            return Ok{};
        }
        if (!it->is_array() || it->empty()) return fileError(name, what);
        out.items.clear();
        for (const json& e : *it) {
            if (!e.is_string() || e.get<std::string>().empty()) return fileError(name, what);
            out.items.push_back(resolve(e.get<std::string>()));
        }
        return Ok{};
    };
    static const char* known[] = {"name", "leafon", "leafoff", "elevation", "buildings", "truth", "parameters",
                                  "generator", "description", "crs", "grid_crs", "grid_res", "extent", "resampling",
                                  "stretch", "buildings_crs", "extent_crs", "extent_of", "offline", "web_cache_mb",
                                  "elevation_encoding", "stream"};
    for (const auto& item : j.items()) {
        const std::string& k = item.key();
        if (std::find_if(std::begin(known), std::end(known), [&](const char* n) { return k == n; }) == std::end(known))
            s.warnings.push_back(name + ": unknown key '" + k + "' ignored");
    }
    if (auto it = j.find("name"); it != j.end()) {
        if (!it->is_string()) return fileError(name, "'name' must be a string");
        s.name = it->get<std::string>();
    }
    if (auto st = sources("leafon", true, s.leafon); !st) return st.error();
    if (auto st = sources("leafoff", true, s.leafoff); !st) return st.error();
    if (auto st = sources("elevation", false, s.elevation); !st) return st.error();
    if (auto st = path(j, "buildings", false, s.buildings, ""); !st) return st.error();
    if (auto it = j.find("truth"); it != j.end() && !it->is_null()) {
        if (!it->is_object()) return fileError(name, "'truth' must be an object {deciduous, conifer, trees}");
        if (auto st = path(*it, "deciduous", false, s.truthDeciduous, "truth."); !st) return st.error();
        if (auto st = path(*it, "conifer", false, s.truthConifer, "truth."); !st) return st.error();
        if (auto st = path(*it, "trees", false, s.truthTrees, "truth."); !st) return st.error();
    }
    if (auto it = j.find("parameters"); it != j.end() && !it->is_null()) {
        if (!it->is_object()) return fileError(name, "'parameters' must be an object");
        if (auto t = it->find("tree_height_m"); t != it->end()) {
            if (!t->is_number() || !(t->get<double>() > 0.0) || !std::isfinite(t->get<double>()))
                return fileError(name, "'parameters.tree_height_m' must be a positive number of metres");
            s.treeHeightM = t->get<double>();
        }
    }
    auto string = [&](const char* key, std::string& out) -> Status {
        auto it = j.find(key);
        if (it == j.end() || it->is_null()) return Ok{};
        if (!it->is_string() || it->get<std::string>().empty())
            return fileError(name, std::string("'") + key + "' must be a non-empty string");
        out = it->get<std::string>();
        return Ok{};
    };
    if (auto st = string("crs", s.crs); !st) return st.error();
    if (auto st = string("grid_crs", s.grid.crs); !st) return st.error();
    if (auto st = string("resampling", s.resampling); !st) return st.error();
    if (auto st = string("stretch", s.stretch); !st) return st.error();
    if (auto st = string("buildings_crs", s.buildingsCrs); !st) return st.error();
    if (auto st = string("extent_crs", s.grid.extentCrs); !st) return st.error();
    if (auto st = string("extent_of", s.grid.extentOf); !st) return st.error();
    if (auto st = string("elevation_encoding", s.elevationEncoding); !st) return st.error();
    if (auto it = j.find("offline"); it != j.end() && !it->is_null()) {
        if (!it->is_boolean()) return fileError(name, "'offline' must be true or false");
        s.offline = it->get<bool>();
    }
    if (auto it = j.find("stream"); it != j.end() && !it->is_null()) {
        if (!it->is_boolean()) return fileError(name, "'stream' must be true or false");
        s.stream = it->get<bool>();
    }
    if (auto it = j.find("web_cache_mb"); it != j.end() && !it->is_null()) {
        if (!it->is_number() || !(it->get<double>() > 0.0) || !std::isfinite(it->get<double>()))
            return fileError(name, "'web_cache_mb' must be a positive number of MiB");
        s.webCacheMb = it->get<double>();
    }
    if (auto it = j.find("grid_res"); it != j.end() && !it->is_null()) {
        if (!it->is_number() || !(it->get<double>() > 0.0) || !std::isfinite(it->get<double>()))
            return fileError(name, "'grid_res' must be a positive number (grid CRS units per pixel)");
        s.grid.resolution = it->get<double>();
    }
    if (auto it = j.find("extent"); it != j.end() && !it->is_null()) {
        if (!it->is_array() || it->size() != 4 ||
            !std::all_of(it->begin(), it->end(), [](const json& v) { return v.is_number(); }))
            return fileError(name, "'extent' must be [W, S, E, N] (degrees, or in 'extent_crs')");
        s.grid.extent = std::array<double, 4>{(*it)[0].get<double>(), (*it)[1].get<double>(), (*it)[2].get<double>(),
                                              (*it)[3].get<double>()};
    }
    if (s.name.empty()) s.name = manifest.parent_path().filename().string();
    return s;
}

} // namespace

Result<GridOptions> parseGridOptions(const SceneSources& sources) {
    GridOptions o;
    if (!sources.grid.crs.empty()) {
        auto crs = Crs::fromUserInput(sources.grid.crs);
        if (!crs) return Error{"--grid-crs: " + crs.message()};
        o.crs = *crs;
    }
    if (sources.grid.resolution) {
        if (!(*sources.grid.resolution > 0.0) || !std::isfinite(*sources.grid.resolution))
            return Error{"--grid-res: a positive number of grid CRS units per pixel expected"};
        o.resolution = sources.grid.resolution;
    }
    o.extent = sources.grid.extent;
    const std::string& in = sources.grid.extentCrs;
    if (!sources.grid.extent) {
        if (!in.empty()) return Error{"--extent-crs: given without --extent"};
    } else if (!sources.grid.extentOf.empty()) {
        return Error{"--extent and --extent-of: give one of them"};
    } else if (in.empty()) {
        // Degrees when the four numbers read as longitudes and latitudes; else (a projected extent, as --extent
        // was before it took degrees) the grid's CRS.
        const auto& e = *sources.grid.extent;
        const bool degrees = std::abs(e[0]) <= 180.0 && std::abs(e[2]) <= 180.0 && std::abs(e[1]) <= 90.0 &&
                             std::abs(e[3]) <= 90.0;
        if (degrees) o.extentCrs = Crs::geographic();
    } else if (in != "grid") {
        auto crs = Crs::fromUserInput(in);
        if (!crs) return Error{"--extent-crs: " + crs.message()};
        o.extentCrs = *crs;
    }
    if (const std::string& of = sources.grid.extentOf; !of.empty() && of != "leafon" && of != "leafoff" && of != "dem")
        return Error{"--extent-of '" + of + "': expected leafon, leafoff or dem"};
    return o;
}

namespace {

Result<ImageryLayer> openImagery(const SourceList& sources, const char* role, const std::optional<Crs>& assumedCrs,
                                 const std::filesystem::path& cacheDir, StretchMode mode) {
    auto mosaic = openMosaic(sources, role, assumedCrs);
    if (!mosaic) return mosaic.error();
    const RasterInfo& first = mosaic->tiles.front();
    if (mosaic->bands < 3)
        return fileError(first.path.string(), std::string(role) + " image needs RGB bands, has " +
                                                  std::to_string(mosaic->bands));
    if (mosaic->type != SampleType::U8 && mosaic->type != SampleType::U16)
        return fileError(first.path.string(), std::string(role) + " image must be 8- or 16-bit, is " +
                                                  sampleTypeName(mosaic->type));
    ImageryLayer layer;
    layer.source = std::move(*mosaic);
    auto stretch = stretchFor(layer.source, cacheDir, mode);
    if (!stretch) return stretch.error();
    layer.stretch = *stretch;
    return layer;
}

/// The layer as it is read on the grid (info), and whether that is its file as it is.
void placeOnGrid(ImageryLayer& layer, const WorkingGrid& grid) {
    const RasterMosaic& m = layer.source;
    const RasterInfo& t = m.tiles.front();
    layer.direct = m.tiles.size() == 1 && !m.hasNodata() && onGridLattice(t, grid) && t.width == grid.width &&
                   t.height == grid.height && grid.georef.crsToPixel(t.georef->origin) == glm::dvec2(0.0);
    RasterInfo& i = layer.info;
    i = RasterInfo{};
    i.path = layer.direct ? t.path : std::filesystem::path();
    i.width = grid.width;
    i.height = grid.height;
    i.channels = 3;
    i.type = m.type;
    i.georef = grid.georef;
    i.tiled = layer.direct && t.tiled;
    i.driver = layer.direct ? t.driver : "warped";
}

/// Where a tile service is read (WebSource.h): over the scene's extent (--extent in its CRS, or --extent-of) when
/// given, else over the other season's footprint (`other`, opened already); at --grid-res in the grid's CRS
/// (`knownGridCrs`, or when the leaf-on is this service chooseWorkingGrid's rule on the service's CRS) when given,
/// else at the other season's pixel size; both measured in the service's CRS at the area's centre.
Result<web::TileArea> tileArea(const GridOptions& options, const RasterMosaic* other,
                               const std::optional<Crs>& knownGridCrs, const Crs& serviceCrs) {
    // The grid's CRS when the leaf-on is this service: chooseWorkingGrid's rule on the service's CRS (a geographic
    // one: the UTM zone of the area's centre).
    const auto gridCrsAt = [&](const Crs& crs, glm::dvec2 centre) {
        if (knownGridCrs) return *knownGridCrs;
        if (!serviceCrs.isGeographic()) return serviceCrs;
        const glm::dvec2 c = convert(crs, Crs::geographic(), centre);
        return Crs::utmAt(c.x, c.y);
    };
    Crs crs;
    glm::dvec2 lo{0.0}, hi{0.0};
    if (options.extent) {
        if (options.extentCrs) crs = *options.extentCrs;
        else if (knownGridCrs) crs = *knownGridCrs;
        else if (!serviceCrs.isGeographic()) crs = serviceCrs;
        else // the grid's CRS would follow from the area the extent gives
            return Error{"--extent: give its CRS with --extent-crs (the grid's follows from a geographic service's area)"};
        lo = {(*options.extent)[0], (*options.extent)[1]};
        hi = {(*options.extent)[2], (*options.extent)[3]};
    } else if (other) {
        crs = other->crs;
        lo = other->min;
        hi = other->max;
    } else {
        return Error{"scene: both seasons are tile services, which cover the world: give --extent W,S,E,N (degrees) "
                     "or --extent-of dem, and --grid-res"};
    }
    Crs resCrs;
    double res = 0;
    if (options.resolution) {
        resCrs = gridCrsAt(crs, 0.5 * (lo + hi));
        res = *options.resolution;
    } else if (other) {
        resCrs = other->finest().georef->crs;
        res = other->finest().georef->pixelSize.x;
    } else {
        return Error{"scene: both seasons are tile services: give --grid-res (the pixel size to read them at)"};
    }
    const auto [mlo, mhi] = boxIn(lo, hi, crs, serviceCrs);
    glm::dvec2 p[2];
    p[0] = convert(crs, resCrs, 0.5 * (lo + hi));
    p[1] = p[0] + glm::dvec2(res, 0.0);
    convert(resCrs, serviceCrs, std::span<glm::dvec2>(p, 2));
    web::TileArea a;
    a.minX = mlo.x, a.minY = mlo.y, a.maxX = mhi.x, a.maxY = mhi.y;
    a.pixelSize = glm::length(p[1] - p[0]);
    if (!std::isfinite(a.minX + a.maxX + a.minY + a.maxY + a.pixelSize))
        return Error{"scene: the area to read the tile service over does not map to its CRS " + serviceCrs.name()};
    return a;
}

/// The part of a service over `grid`'s box widened by `margin` of its size each side, at the grid's pixel (measured at
/// its centre in the service's CRS) or coarser so that the area is at most `maxSide` pixels a side. `what` names the
/// input in the error when they do not map to the service's CRS.
Result<web::TileArea> areaOverGrid(const WorkingGrid& grid, double margin, double maxSide, const Crs& serviceCrs,
                                   const char* what) {
    const glm::dvec2 lo = grid.min(), hi = grid.max(), m = margin * (hi - lo);
    const auto [a, b] = boxIn(lo - m, hi + m, grid.georef.crs, serviceCrs);
    glm::dvec2 p[2] = {0.5 * (lo + hi), 0.5 * (lo + hi) + glm::dvec2(grid.georef.pixelSize.x, 0.0)};
    convert(grid.georef.crs, serviceCrs, std::span<glm::dvec2>(p, 2));
    web::TileArea t;
    t.minX = a.x, t.minY = a.y, t.maxX = b.x, t.maxY = b.y;
    t.pixelSize = std::max(glm::length(p[1] - p[0]), std::max(b.x - a.x, b.y - a.y) / maxSide);
    if (!std::isfinite(t.minX + t.maxX + t.minY + t.maxY + t.pixelSize))
        return Error{std::string("scene: the area to read the ") + what + " over does not map to its CRS " +
                     serviceCrs.name()};
    return t;
}

/// A tile service's GDAL description over the area `areaIn` gives in the service's CRS: a WMTS layer's
/// (describeWmts), else an XYZ/TMS template's in Web Mercator (describeTileService).
Result<std::filesystem::path> describeService(const std::string& url,
                                              const std::function<Result<web::TileArea>(const Crs&)>& areaIn,
                                              const std::filesystem::path& cacheDir, const web::ServiceOptions& run) {
    if (web::isWmts(url)) return web::describeWmts(url, areaIn, cacheDir, run);
    auto mercator = Crs::fromEpsg(3857);
    if (!mercator) return mercator.error();
    auto area = areaIn(*mercator);
    if (!area) return area.error();
    return web::describeTileService(url, *area, cacheDir, run);
}

} // namespace

bool isTileService(const SourceList& s) {
    return s.items.size() == 1 && (web::isTileTemplate(s.items.front().string()) || web::isWmts(s.items.front().string()));
}

Result<ImageryLayer> serviceLayerOnGrid(const Scene& scene, const std::string& role, const WorkingGrid& grid,
                                        const std::filesystem::path& cacheDir, int maxConnections) {
    const bool on = role == "leafon";
    assert((on || role == "leafoff") && "serviceLayerOnGrid(): leafon or leafoff");
    const SourceList& given = on ? scene.sources.leafon : scene.sources.leafoff;
    assert(isTileService(given) && "serviceLayerOnGrid(): a season from a tile service");
    web::ServiceOptions run;
    run.offline = scene.sources.offline;
    if (scene.sources.webCacheMb > 0) run.cacheMb = scene.sources.webCacheMb;
    run.maxConnections = maxConnections;
    // The grid's box and pixel size in the service's CRS (the pixel measured at the grid's centre).
    const auto areaIn = [&](const Crs& serviceCrs) {
        return areaOverGrid(grid, 0.0, std::numeric_limits<double>::infinity(), serviceCrs, "streamed tile service");
    };
    auto xml = describeService(given.items.front().string(), areaIn, cacheDir, run);
    if (!xml) return xml.error();
    SourceList list;
    list.items = {*xml};
    std::optional<Crs> assumed;
    if (!scene.sources.crs.empty())
        if (auto crs = Crs::fromUserInput(scene.sources.crs)) assumed = *crs;
    const ImageryLayer& full = on ? scene.leafon : scene.leafoff;
    auto layer = openImagery(list, on ? "leaf-on" : "leaf-off", assumed, cacheDir, StretchMode::Auto);
    if (!layer) return layer.error();
    layer->stretch = full.stretch; // the colours of the full-resolution season, whatever the zoom's statistics
    placeOnGrid(*layer, grid);
    layer->resampling = full.resampling;
    return layer;
}

Result<ImageryLayer> openImageryLayer(const SourceList& sources, const std::string& role,
                                      const std::filesystem::path& cacheDir, const WorkingGrid* grid,
                                      const std::optional<Crs>& assumedCrs, Resampling resampling,
                                      StretchMode stretch) {
    auto layer = openImagery(sources, role.c_str(), assumedCrs, cacheDir, stretch);
    if (!layer) return layer.error();
    const RasterInfo& first = layer->source.tiles.front();
    const WorkingGrid own{*first.georef, first.width, first.height};
    placeOnGrid(*layer, grid ? *grid : own);
    layer->resampling = resampling;
    return layer;
}

Result<Scene> loadScene(const SceneSources& sources, const std::filesystem::path& cacheDir) {
    Scene scene;
    scene.sources = sources;
    if (sources.leafon.empty()) return Error{"scene: no leaf-on image given (--leafon or a manifest)"};
    if (sources.leafoff.empty()) return Error{"scene: no leaf-off image given (--leafoff or a manifest)"};
    std::optional<Crs> assumed;
    if (!sources.crs.empty()) {
        auto crs = Crs::fromUserInput(sources.crs);
        if (!crs) return Error{"--crs: " + crs.message()};
        assumed = *crs;
    }
    auto options = parseGridOptions(sources);
    if (!options) return options.error();
    auto resampling = parseResampling(sources.resampling);
    if (!resampling) return resampling.error();
    scene.resampling = *resampling;
    auto stretch = parseStretchMode(sources.stretch);
    if (!stretch) return stretch.error();

    // A season from a tile service (WebSource.h) is read as a GDAL WMS description of the part of the service the
    // scene covers, written into the cache: over the scene's extent or the other season's footprint, so the seasons
    // from files (and the DEM for --extent-of dem) are opened first.
    if (sources.offline)
        for (const SourceList* l : {&sources.leafon, &sources.leafoff, &sources.elevation})
            for (const auto& item : l->items)
                if (web::isUrl(item.string()) && !web::isTileTemplate(item.string()) && !web::isWmts(item.string()))
                    return fileError(item.string(), "--offline reads tile services from the disk cache; a raster by "
                                                    "URL is read over the network");
    const SourceList* given[2] = {&sources.leafon, &sources.leafoff};
    const char* roles[2] = {"leaf-on", "leaf-off"};
    const bool service[2] = {isTileService(sources.leafon), isTileService(sources.leafoff)};
    ImageryLayer* layers[2] = {&scene.leafon, &scene.leafoff};
    std::optional<RasterMosaic> demMosaic;
    const bool demService = isTileService(sources.elevation);
    web::ServiceOptions run;
    run.offline = sources.offline;
    if (sources.webCacheMb > 0) run.cacheMb = sources.webCacheMb;
    auto encoding = parseHeightEncoding(sources.elevationEncoding);
    if (!encoding) return encoding.error();
    if (demService && *encoding == HeightEncoding::Value)
        return fileError(sources.elevation.items.front().string(),
                         "a DEM from a tile service needs --dem-encoding terrarium|mapbox (how its tiles' colours "
                         "encode heights)");
    const auto openDem = [&]() -> Result<Ok> {
        if (demMosaic || sources.elevation.empty()) return Ok{};
        SourceList list = sources.elevation;
        if (demService) {
            // A DEM service is read over the grid with a quarter's margin each side (as loadHeightfield reads a
            // DEM), at the grid's pixel size or coarser, so that it is at most 4096 samples a side.
            const std::string url = list.items.front().string();
            const auto areaIn = [&](const Crs& serviceCrs) {
                return areaOverGrid(scene.grid, 0.25, 4096.0, serviceCrs, "DEM service");
            };
            auto xml = describeService(url, areaIn, cacheDir, run);
            if (!xml) return xml.error();
            list.items = {*xml};
        }
        auto dem = openMosaic(list, "DEM", assumed);
        if (!dem) return dem.error();
        demMosaic = std::move(*dem);
        return Ok{};
    };
    for (int pass = 0; pass < 2; ++pass) {
        if (pass == 1) {
            // The footprint --extent-of names, as an extent in its CRS.
            if (const std::string& of = sources.grid.extentOf; !of.empty()) {
                const RasterMosaic* m = nullptr;
                if (of == "dem") {
                    if (sources.elevation.empty()) return Error{"--extent-of dem: no DEM given (--dem)"};
                    if (demService) return Error{"--extent-of dem: the DEM is a tile service, which covers the world"};
                    if (auto st = openDem(); !st) return st.error();
                    m = &*demMosaic;
                } else {
                    const int i = of == "leafon" ? 0 : 1;
                    if (service[i])
                        return Error{"--extent-of " + of + ": the " + roles[i] +
                                     " is a tile service, which covers the world"};
                    m = &layers[i]->source;
                }
                options->extent = std::array<double, 4>{m->min.x, m->min.y, m->max.x, m->max.y};
                options->extentCrs = m->crs;
            }
        }
        for (int i = 0; i < 2; ++i) {
            if (service[i] != (pass == 1)) continue;
            SourceList s = *given[i];
            if (service[i]) {
                const RasterMosaic* other = service[1 - i] ? nullptr : &layers[1 - i]->source;
                // The grid's CRS, for --grid-res: as chooseWorkingGrid picks it from the leaf-on (this service's
                // when the leaf-on is this service).
                const bool leafonOpened = !service[0] || i == 1;
                const auto areaIn = [&](const Crs& serviceCrs) {
                    std::optional<Crs> gridCrs; // none: the leaf-on is this service, the grid's CRS follows from it
                    if (options->crs) gridCrs = *options->crs;
                    else if (leafonOpened)
                        gridCrs = defaultGridCrs(scene.leafon.source.crs, scene.leafon.source.min, scene.leafon.source.max);
                    return tileArea(*options, other, gridCrs, serviceCrs);
                };
                const std::string url = s.items.front().string();
                auto xml = describeService(url, areaIn, cacheDir, run);
                if (!xml) return xml.error();
                s.items = {*xml};
            }
            auto layer = openImagery(s, roles[i], assumed, cacheDir, *stretch);
            if (!layer) return layer.error();
            *layers[i] = std::move(*layer);
        }
    }
    if (sources.grid.extent && sources.grid.extentCrs.empty() && options->extentCrs)
        scene.notes.push_back("--extent read as degrees (WGS 84 longitudes, latitudes); --extent-crs grid reads it in "
                              "the grid's CRS");
    auto grid = chooseWorkingGrid(scene.leafon.source, scene.leafoff.source, *options, sources.leafon.describe(),
                                  sources.leafoff.describe());
    if (!grid) return grid.error();
    scene.grid = *grid;
    placeOnGrid(scene.leafon, scene.grid);
    placeOnGrid(scene.leafoff, scene.grid);
    scene.leafon.resampling = scene.leafoff.resampling = scene.resampling;
    for (const ImageryLayer* l : {&scene.leafon, &scene.leafoff})
        if (!l->direct)
            scene.notes.push_back(std::string(l == &scene.leafon ? "leaf-on " : "leaf-off ") + "(" +
                                  std::to_string(l->source.tiles.size()) + " file" +
                                  (l->source.tiles.size() == 1 ? "" : "s") + ", " + l->source.crs.name() +
                                  ") is warped onto the working grid when prepared");

    const Georef& a = scene.grid.georef;
    const int w = scene.grid.width, h = scene.grid.height;
    scene.frame = GeoFrame(a.crs, a.pixelToCrs({w * 0.5, h * 0.5}));
    scene.localMin = glm::dvec2(1e300);
    scene.localMax = glm::dvec2(-1e300);
    for (int i = 0; i <= 4; ++i)
        for (int k = 0; k <= 4; ++k) {
            const glm::dvec3 p = scene.frame.toLocal(a.crs, a.pixelToCrs({w * i / 4.0, h * k / 4.0}));
            scene.localMin = glm::min(scene.localMin, glm::dvec2(p));
            scene.localMax = glm::max(scene.localMax, glm::dvec2(p));
        }
    {
        const glm::dvec3 p0 = scene.frame.toLocal(a.crs, a.pixelToCrs({w * 0.5, h * 0.5}));
        const glm::dvec3 p1 = scene.frame.toLocal(a.crs, a.pixelToCrs({w * 0.5 + 1.0, h * 0.5}));
        scene.gsd = glm::length(glm::dvec2(p1 - p0));
    }

    if (!sources.elevation.empty()) {
        if (auto st = openDem(); !st) return st.error();
        auto hf = loadHeightfield(*demMosaic, scene.grid, *encoding);
        if (!hf && demService)
            if (auto tile = web::tileFailure(demMosaic->tiles.front().path, hf.message())) return *tile;
        if (!hf) return hf.error();
        if (hf->filledSamples > 0)
            scene.notes.push_back(sources.elevation.describe() + ": filled " + std::to_string(hf->filledSamples) +
                                  " NaN/nodata samples from their neighbours");
        scene.elevation = std::move(*hf);
    }
    return scene;
}

} // namespace seasonview
