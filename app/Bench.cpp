// The frame benchmark: per-frame counters along a camera path, a summary, an interleaved comparison of modes and a
// plot of frame time and coverage over the path.
#include "Bench.h"
#include "WebSource.h"
#include "StreamedPyramid.h"
#include "CityJob.h"
#include "Plot.h"
#include "RenderJob.h"

#include "CanopyClipmapGL.h"
#include "CanopyRendererGL.h"
#include "TrunksGL.h"

#include "AtomicFile.h"
#include "CameraPath.h"
#include "gl/FrameStages.h"
#include "gl/GlDebug.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

#include <malloc.h>
#include <unistd.h>

namespace seasonview::app {

namespace {

struct FrameRow {
    int frame = 0;
    Camera camera;
    double cpuMs = 0, gpuMs = 0, frameMs = 0;
    double streamMs = 0; // of cpuMs: the frame's streaming (clipmap uploads, the canopy's derivation, trunk search)
    std::vector<gl::StageTime> stages; // --stages: the frame's stages, each issued then waited for
    double cityCpuMs = 0; // issuing the city's paging and draws (the per-call driver cost the atlas tree saves)
    double cityUpdateMs = 0; // of which the paging (update(): requests, pager, uploads and deletes)
    int drawCalls = 1;
    std::int64_t triangles = 0, texelsUploaded = 0, exposedTexels = 0, residentBytes = 0, loaderCacheBytes = 0,
                 rssBytes = 0, heapInUseBytes = 0, heapMappedBytes = 0;
    // The terrain's elevation clipmap (terrain/GeometryClipmapGL): its own uploads and texture memory. Its loader's
    // cache is in loaderCacheBytes with the imagery's.
    std::int64_t elevationTexelsUploaded = 0, elevationResidentBytes = 0;
    int blocksMissing = 0;
    int canopyBlocksDerived = 0; // canopy view: blocks the segmentation rule ran on this frame
    int canopyBlocksPending = 0; // canopy view: resident blocks waiting for a neighbour or the budget
    int canopyBlocksUnread = 0;  // canopy view: resident blocks no canopy lookup read lately (not derived)
    int canopyBlocksOnDemand = 0; // canopy view: of the blocks derived, those derived because a lookup read them
    int trunkSearches = 0;       // canopy view with trunks: 1 when the crown centres were searched this frame
    int runOrder = 0;            // the frame's place among all modes' measured frames as they ran (interleaved)
    double coverage = NAN;
    city::CityFrameStats city; // zeros without a city
};

struct Mode {
    std::string label;
    RendererKind renderer = RendererKind::Clipmap;
    CenterPlacement centers = CenterPlacement::Footprint;
    float anisotropy = 8.0f;
    int canopyLayers = -1;        // -1: as --view says; 0: no canopy (leaf-on terrain); N: canopy view, N layers
    bool perFrameSegmentation = false; // the canopy layer re-derived every frame (the paper's per-frame evaluation)
    std::optional<bool> canopyLevelsRead; // compare canopy-levels: derive only the blocks read (unset: --canopy-levels)
    std::optional<CanopyDerivation> canopyDerivation; // compare canopy-derive (unset: --canopy-derive)
    // compare canopy-pyramid: off derives every block as it is read, on reads the precomputed layer (built for this
    // mode's parameters first when the cache has none); unset: the precomputed layer where the cache has it.
    std::optional<bool> canopyPyramid;
    bool terrainOnly = false;     // scene=terrain: the relief alone (geometry, no imagery, no canopy)
    std::optional<CanopyDrawMode> canopyDraw; // canopy-draw=...: this mode's way of drawing the layers
    std::optional<city::CityMode> cityMode; // the city model drawn after the terrain (nullopt: none)
    city::AtlasUpload cityUpload = city::AtlasUpload::Auto;
    bool cityOcclusion = true;
    bool cityFlush = true;        // city-flush=off,on: CitySettings::flushFirst
    city::MapOcclusion cityMapOcclusion = city::MapOcclusion::Auto; // city-map-occlusion=...: CitySettings::mapOcclusion
    bool drawTerrain = true;      // terrain=off: the city drawn alone (the imagery clipmap still streams for roofs)
    TerrainShading terrainShading = TerrainShading::Auto;
    std::optional<bool> streamed; // source=prepared|stream: the seasons' pyramids (unset: as the scene says, --stream)
    std::unique_ptr<city::CityRendererGL> city;
    std::unique_ptr<ClipmapGL> clipmap;
    std::unique_ptr<CanopyClipmapGL> canopy;
    std::unique_ptr<CanopyRendererGL> canopyRenderer;
    std::unique_ptr<TrunksGL> trunks;
    std::unique_ptr<ClipmapTerrainRendererGL> clipRenderer;
    std::unique_ptr<ReferenceRendererGL> reference;
    std::vector<FrameRow> rows;
    // The clipmaps' own running totals of texels uploaded when the first recorded frame began (summary.json's
    // totals: what they reported over the recorded frames, against the sum of frames.csv's per-frame figures).
    std::int64_t clipmapTotalAtStart = 0, elevationTotalAtStart = 0;
};

std::int64_t residentSetBytes() {
    std::ifstream f("/proc/self/statm");
    std::int64_t pages = 0, rss = 0;
    f >> pages >> rss;
    return rss * std::int64_t(::sysconf(_SC_PAGESIZE));
}

// malloc's own view (all arenas): bytes handed out and bytes it holds from the kernel. With RSS these tell a leak
// (in use grows) from fragmentation or retained free memory (mapped grows, in use does not) from memory outside
// malloc (driver mappings: neither grows).
void heapBytes(std::int64_t& inUse, std::int64_t& mapped) {
    const struct mallinfo2 mi = ::mallinfo2();
    inUse = std::int64_t(mi.uordblks + mi.hblkhd);
    mapped = std::int64_t(mi.arena + mi.hblkhd);
}

double percentile(std::vector<double> v, double p) {
    v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
    if (v.empty())
        return NAN;
    std::sort(v.begin(), v.end());
    const double r = p / 100.0 * double(v.size() - 1);
    const size_t i = size_t(r);
    return i + 1 < v.size() ? v[i] + (v[i + 1] - v[i]) * (r - double(i)) : v[i];
}

nlohmann::json figure(const std::vector<double>& v) {
    auto num = [](double x) { return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr); };
    return {{"median", num(percentile(v, 50))}, {"p95", num(percentile(v, 95))}, {"max", num(percentile(v, 100))}};
}

/// A city mode's figures: per-frame medians/maxima of its counters and the capacity they must stay under.
nlohmann::json cityFigures(const Mode& m) {
    std::vector<double> nodes, binds, calls, resident, queue, coarser, cpu, update, upload, uploaded, wait, occluded,
        queries, waits, drawnTriangles, maps, mapsMissing, poolBytes, movedBytes;
    for (const FrameRow& r : m.rows) {
        drawnTriangles.push_back(double(r.city.triangles));
        maps.push_back(r.city.blockMaps);
        mapsMissing.push_back(r.city.blockMapsNotResident);
        poolBytes.push_back(double(r.city.blockMapPoolBytes));
        movedBytes.push_back(double(r.city.blockMapMovedBytes));
        cpu.push_back(r.cityCpuMs);
        update.push_back(r.cityUpdateMs);
        upload.push_back(r.city.uploadMs);
        uploaded.push_back(double(r.city.uploadedBytes));
        wait.push_back(r.city.waitMs);
        occluded.push_back(r.city.occludedNodes);
        queries.push_back(r.city.occlusionQueries);
        waits.push_back(r.city.occlusionWaits);
        nodes.push_back(r.city.atlasNodes);
        binds.push_back(r.city.textureBinds);
        calls.push_back(r.city.drawCalls);
        resident.push_back(double(r.city.residentBytes));
        queue.push_back(double(r.city.loaderQueue));
        coarser.push_back(r.city.coarserThanWanted);
    }
    return {{"mode", city::cityModeName(*m.cityMode)},
            {"upload", city::atlasUploadName(m.cityUpload)},
            {"atlases_decoded", m.city->decodesAtlases()},
            {"occlusion", m.city->settings().occlusion &&
                              (*m.cityMode == city::CityMode::Atlas || *m.cityMode == city::CityMode::BlockMap)},
            {"flush_first", m.city->settings().flushFirst},
            {"map_occlusion", city::mapOcclusionName(m.city->settings().mapOcclusion)},
            {"map_occlusion_resolved", city::mapOcclusionName(m.city->mapOcclusionUsed())},
            {"atlas_nodes", figure(nodes)},
            {"occluded_nodes", figure(occluded)},
            {"occlusion_queries", figure(queries)},
            {"occlusion_waits", figure(waits)},
            {"texture_binds", figure(binds)},
            {"draw_calls", figure(calls)},
            {"cpu_ms", figure(cpu)},
            {"update_ms", figure(update)},
            {"upload_ms", figure(upload)},
            {"uploaded_bytes", figure(uploaded)},
            {"wait_ms", figure(wait)},
            {"resident_bytes", figure(resident)},
            {"capacity_bytes", m.city->settings().capacityBytes},
            {"loader_queue", figure(queue)},
            {"coarser_than_wanted", figure(coarser)},
            {"triangles", m.city->triangles()},
            {"drawn_triangles", figure(drawnTriangles)},
            {"block_maps", figure(maps)},
            {"block_maps_not_resident", figure(mapsMissing)},
            {"block_map_pool_bytes", figure(poolBytes)},
            {"block_map_moved_bytes", figure(movedBytes)},
            {"block_map_error_px", m.city->settings().blockMapErrorPx}};
}

// "centers=concentric,offset,footprint" or "renderer=clipmap,reference" -> modes.
// One value of --compare KEY=V1,V2,... applied to a mode made from the other options.
Status applyCompareValue(const BenchSettings& a, const std::string& key, const std::string& v, Mode& m) {
    if (key == "centers") {
        auto c = parsePlacement(v);
        if (!c)
            return Error{"--compare: unknown centers '" + v + "' (expected " + placementNames() + ")"};
        m.centers = *c;
    } else if (key == "aniso") {
        char* end = nullptr;
        const float x = std::strtof(v.c_str(), &end);
        if (v.empty() || *end != '\0' || !(x >= 1.0f && x <= kMaxAnisotropy))
            return Error{"--compare: aniso '" + v + "' is not a number in 1..16"};
        m.anisotropy = x;
    } else if (key == "canopy") {
        auto c = parseCanopyArgs(v, a.canopy.method, a.canopy.k);
        if (!c)
            return Error{"--compare: canopy '" + v + "' is not off or 1..32"};
        m.canopyLayers = c->layers;
    } else if (key == "canopy-draw") {
        // The canopy view with --canopy-layers layers, drawn each way.
        CanopyRenderSettings d;
        if (auto st = parseCanopyDrawArg(v, d); !st)
            return Error{"--compare: canopy-draw '" + v + "' (expected layers|march)"};
        auto c = parseCanopyArgs(a.canopy.layers, a.canopy.method, a.canopy.k);
        if (!c)
            return Error{c.message()};
        m.canopyLayers = std::max(1, c->layers);
        m.canopyDraw = d.draw;
    } else if (key == "scene") {
        // terrain: the geometry clipmaps shaded, no imagery; full: both seasons (leaf-off under the crowns,
        // leaf-on elsewhere), the stacked canopy layers (--canopy-layers, default 16) and the trunks.
        if (v == "terrain") {
            m.terrainOnly = true;
            m.canopyLayers = 0;
        } else if (v == "full") {
            auto c = parseCanopyArgs(a.canopy.layers, a.canopy.method, a.canopy.k);
            if (!c)
                return Error{c.message()};
            m.canopyLayers = std::max(1, c->layers);
        } else
            return Error{"--compare: scene '" + v + "' (expected terrain|full)"};
    } else if (key == "city") {
        if (v == "off") {
            m.cityMode.reset();
        } else {
            m.cityMode = city::parseCityMode(v);
            if (!m.cityMode) return Error{"--compare: city '" + v + "' (expected atlas|original|flat|blockmap|off)"};
        }
    } else if (key == "city-upload") {
        // The atlas city (or --city's mode) with its BC atlases uploaded each way.
        auto u = city::parseAtlasUpload(v);
        if (!u) return Error{"--compare: city-upload '" + v + "' (expected auto|compressed|decoded)"};
        if (!m.cityMode) m.cityMode = city::CityMode::Atlas;
        m.cityUpload = *u;
    } else if (key == "city-occlusion") {
        // The atlas city (or --city's mode) drawn with and without occlusion culling.
        if (v != "on" && v != "off") return Error{"--compare: city-occlusion '" + v + "' (expected on|off)"};
        if (!m.cityMode) m.cityMode = city::CityMode::Atlas;
        m.cityOcclusion = v == "on";
    } else if (key == "city-flush") {
        // The city (--city's mode, default atlas) paged and issued after the terrain was handed to the GPU, or not.
        if (v != "on" && v != "off") return Error{"--compare: city-flush '" + v + "' (expected on|off)"};
        if (!m.cityMode) m.cityMode = city::CityMode::Atlas;
        m.cityFlush = v == "on";
    } else if (key == "city-map-occlusion") {
        // Blockmap mode: the maps tested for occlusion drawn under conditional rendering or after reading the answers.
        auto o = city::parseMapOcclusion(v);
        if (!o) return Error{"--compare: city-map-occlusion '" + v + "' (expected auto|conditional|readback)"};
        if (!m.cityMode) m.cityMode = city::CityMode::BlockMap;
        m.cityMapOcclusion = *o;
    } else if (key == "source") {
        // Seasons from tile services prepared whole vs streamed level by level (--stream), over the same path.
        if (v != "prepared" && v != "stream") return Error{"--compare: source '" + v + "' (expected prepared|stream)"};
        m.streamed = v == "stream";
    } else if (key == "terrain-shading") {
        auto t = parseTerrainShading(v);
        if (!t) return Error{"--compare: terrain-shading '" + v + "' (expected auto|forward|deferred)"};
        m.terrainShading = *t;
    } else if (key == "terrain") {
        // The city (--city, default atlas) over the terrain and alone.
        if (v != "on" && v != "off") return Error{"--compare: terrain '" + v + "' (expected on|off)"};
        if (!m.cityMode) m.cityMode = city::CityMode::Atlas;
        m.drawTerrain = v == "on";
    } else if (key == "segmentation") {
        if (v != "upload" && v != "perframe")
            return Error{"--compare: segmentation '" + v + "' (expected upload|perframe)"};
        m.perFrameSegmentation = v == "perframe";
    } else if (key == "canopy-levels") {
        if (v != "read" && v != "all") return Error{"--compare: canopy-levels '" + v + "' (expected all|read)"};
        m.canopyLevelsRead = v == "read";
    } else if (key == "canopy-pyramid") {
        if (v != "off" && v != "on") return Error{"--compare: canopy-pyramid '" + v + "' (expected off|on)"};
        m.canopyPyramid = v == "on";
    } else if (key == "canopy-derive") {
        CanopyRenderSettings c;
        if (!parseCanopyDeriveArg(v, c)) return Error{"--compare: canopy-derive '" + v + "' (expected auto|cpu|gpu)"};
        m.canopyDerivation = c.derivation;
    } else if (v == "reference") {
        m.renderer = RendererKind::Reference;
    } else if (v != "clipmap") {
        return Error{"--compare: unknown renderer '" + v + "' (expected clipmap|reference)"};
    }
    return Ok{};
}

Result<std::vector<Mode>> parseModes(const BenchSettings& a) {
    std::vector<Mode> modes;
    auto base = [&]() -> Result<Mode> {
        Mode m;
        auto reference = a.clipmap.referenceRenderer();
        if (!reference)
            return reference.error();
        m.renderer = *reference ? RendererKind::Reference : RendererKind::Clipmap;
        auto c = a.clipmap.placement();
        if (!c)
            return c.error();
        m.centers = *c;
        if (!(a.imagery.aniso >= 1.0f && a.imagery.aniso <= kMaxAnisotropy))
            return Error{"--aniso: expected 1..16"};
        m.anisotropy = a.imagery.aniso;
        if (a.city.mode != "off") {
            m.cityMode = city::parseCityMode(a.city.mode);
            if (!m.cityMode) return Error{"--city '" + a.city.mode + "': expected atlas|original|flat|blockmap|off"};
        }
        auto upload = city::parseAtlasUpload(a.city.upload);
        if (!upload) return Error{"--city-upload '" + a.city.upload + "': expected auto|compressed|decoded"};
        m.cityUpload = *upload;
        if (a.city.occlusion != "on" && a.city.occlusion != "off")
            return Error{"--city-occlusion '" + a.city.occlusion + "': expected on|off"};
        m.cityOcclusion = a.city.occlusion == "on";
        auto mapOcclusion = city::parseMapOcclusion(a.city.mapOcclusion);
        if (!mapOcclusion)
            return Error{"--city-map-occlusion '" + a.city.mapOcclusion + "': expected auto|conditional|readback"};
        m.cityMapOcclusion = *mapOcclusion;
        if (a.imagery.terrain != "on" && a.imagery.terrain != "off")
            return Error{"--terrain '" + a.imagery.terrain + "': expected on|off"};
        m.drawTerrain = a.imagery.terrain == "on";
        auto shading = parseTerrainShading(a.imagery.terrainShading);
        if (!shading) return Error{"--terrain-shading '" + a.imagery.terrainShading + "': expected auto|forward|deferred"};
        m.terrainShading = *shading;
        return m;
    };
    // The city alone: nothing else may need the terrain pass.
    auto checkTerrainOff = [&](const std::vector<Mode>& ms) -> Status {
        for (const Mode& m : ms) {
            if (m.drawTerrain) continue;
            if (!m.cityMode)
                return Error{"terrain off draws only the city: give --city atlas|original|flat (mode " + m.label + ")"};
            if (m.renderer == RendererKind::Reference)
                return Error{"terrain off needs the clipmap renderer (mode " + m.label + ")"};
            const bool canopyView = m.canopyLayers >= 0 ? m.canopyLayers > 0 : a.imagery.view == "canopy";
            if (canopyView)
                return Error{"terrain off: the canopy is drawn with the terrain, not without (mode " + m.label + ")"};
        }
        return Ok{};
    };
    if (a.compare.empty()) {
        auto m = base();
        if (!m)
            return m.error();
        m->label = m->renderer == RendererKind::Reference ? "reference" : placementName(m->centers);
        modes.push_back(std::move(*m));
        if (auto st = checkTerrainOff(modes); !st)
            return st.error();
        return modes;
    }
    const size_t eq = a.compare.find('=');
    const std::string key = a.compare.substr(0, eq);
    if (eq == std::string::npos || (key != "centers" && key != "renderer" && key != "aniso" && key != "canopy" &&
                                    key != "canopy-draw" && key != "segmentation" && key != "canopy-levels" && key != "canopy-derive" &&
                                    key != "canopy-pyramid" &&
                                    key != "scene" &&
                                    key != "city" &&
                                    key != "city-upload" && key != "city-occlusion" && key != "city-flush" &&
                                    key != "city-map-occlusion" && key != "terrain" &&
                                    key != "terrain-shading" && key != "source"))
        return Error{"--compare '" + a.compare +
                     "': expected centers=A,B,..., renderer=clipmap,reference, aniso=A,B,..., canopy=off,N,..., "
                     "canopy-draw=layers,march, segmentation=upload,perframe, canopy-levels=all,read, canopy-derive=gpu,cpu, "
                     "canopy-pyramid=off,on, "
                     "scene=terrain,full or "
                     "city=atlas,original,flat,off, city-upload=compressed,decoded,auto, city-occlusion=off,on, "
                     "city-flush=off,on, city-map-occlusion=conditional,readback, terrain=on,off, "
                     "terrain-shading=forward,deferred or source=prepared,stream"};
    std::stringstream list(a.compare.substr(eq + 1));
    std::string v;
    while (std::getline(list, v, ',')) {
        auto m = base();
        if (!m)
            return m.error();
        if (auto st = applyCompareValue(a, key, v, *m); !st) return st.error();
        m->label = key + "=" + v;
        modes.push_back(std::move(*m));
    }
    if (modes.size() < 2)
        return Error{"--compare '" + a.compare + "': give at least two values"};
    if (auto st = checkTerrainOff(modes); !st)
        return st.error();
    return modes;
}

// One benchmark run: the modes' renderers on one headless context, the warm-up, and the measured frames interleaved
// over the path. The modes (owned by the caller) must die while the context lives.
class BenchRun {
public:
    BenchRun(const Scene& scene, const BenchSettings& a, std::vector<Mode>& modes, const CanopyRenderSettings& canopy,
             ImageryView view, std::filesystem::path cache)
        : m_scene(scene), m_a(a), m_modes(modes), m_canopy(canopy), m_cache(std::move(cache)), m_w(a.width),
          m_h(a.height), m_target(a.width, a.height), m_scratch(a.width, a.height),
          m_timer(gl::Query::create(GL_TIME_ELAPSED)) {
        m_imagery.view = view;
    }

    // Before the context: both seasons' pyramids and the elevation, when a mode streams them.
    // pyramids[0]: prepared whole; pyramids[1]: streamed (--stream, compare source=stream); each when a mode uses it.
    static Status prepareInputs(const Scene& scene, const std::vector<Mode>& modes, const std::filesystem::path& cache,
                                std::array<std::vector<ImagePyramid>, 2>& pyramids,
                                std::optional<ImagePyramid>& elevation);
    // Every mode's renderers (reference, or clipmaps, terrain, canopy and trunks), then the city's.
    Status createRenderers(const std::array<std::vector<ImagePyramid>, 2>& pyramids,
                           const std::optional<ImagePyramid>& elevation);
    // The warm-up at the path's start, a fully loaded view, then the measured frames; a damaged cache tile stops it.
    Status run(const CameraPath& path, const std::filesystem::path& out);
    double seconds() const { return m_seconds; }

private:
    Status createClipmapMode(Mode& m, const std::vector<ImagePyramid>& pyramids,
                             const std::optional<ImagePyramid>& elevation);
    Status createCanopy(Mode& m, const std::vector<ImagePyramid>& pyramids, int layers);
    Status createCities();
    void checkDamage(Mode& m);
    void frame(Mode& m, const Camera& cam, int frame, bool record);
    void stream(Mode& m, const Camera& cam, FrameRow& row, ClipmapFrameStats& cs, ClipmapFrameStats& es);
    void draw(Mode& m, const Camera& cam, FrameRow& row);
    void record(Mode& m, const Camera& cam, FrameRow& row, const ClipmapFrameStats& cs, const ClipmapFrameStats& es);

    using Clock = std::chrono::steady_clock;
    static double ms(Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

    const Scene& m_scene;
    const BenchSettings& m_a;
    std::vector<Mode>& m_modes;
    CanopyRenderSettings m_canopy;
    std::filesystem::path m_cache;
    int m_w, m_h;
    gl::RenderTarget m_target, m_scratch;
    gl::Query m_timer;
    ImagerySettings m_imagery;
    std::string m_damaged; // the first damaged cache tile's message
    int m_recorded = 0;
    double m_seconds = 0.0;
};

Status BenchRun::prepareInputs(const Scene& scene, const std::vector<Mode>& modes, const std::filesystem::path& cache,
                               std::array<std::vector<ImagePyramid>, 2>& pyramids,
                               std::optional<ImagePyramid>& elevation) {
    const bool anyClipmap =
        std::any_of(modes.begin(), modes.end(), [](const Mode& m) { return m.renderer == RendererKind::Clipmap; });
    if (!anyClipmap && !scene.warped()) return Ok{}; // the reference reads warped seasons' level 0
    for (int streamed = 0; streamed < 2; ++streamed) {
        if (std::none_of(modes.begin(), modes.end(),
                         [&](const Mode& m) { return m.streamed.value_or(scene.sources.stream) == bool(streamed); }))
            continue;
        if (streamed && !isTileService(scene.sources.leafon) && !isTileService(scene.sources.leafoff))
            return Error{"--stream / --compare source=stream: neither season is a tile service"};
        Scene s = scene;
        s.sources.stream = bool(streamed);
        auto p = preparePyramids(s, cache);
        if (!p) return p.error();
        pyramids[size_t(streamed)] = std::move(*p);
    }
    auto e = prepareElevation(scene, cache);
    if (!e) return e.error();
    elevation = std::move(*e);
    return Ok{};
}

Status BenchRun::createRenderers(const std::array<std::vector<ImagePyramid>, 2>& sources,
                                 const std::optional<ImagePyramid>& elevation) {
    for (Mode& m : m_modes) {
        const std::vector<ImagePyramid>& pyramids = sources[m.streamed.value_or(m_scene.sources.stream) ? 1 : 0];
        if (m.renderer == RendererKind::Reference) {
            ReferenceOptions ro;
            ro.anisotropy = m.anisotropy;
            if (auto st = refuseStreamed(pyramids, "the reference renderer"); !st) return st;
            ro.levelZero = levelZeroOf(m_scene, pyramids);
            auto r = ReferenceRendererGL::create(m_scene, ro);
            if (!r) return r.error();
            m.reference = std::move(*r);
        } else if (auto st = createClipmapMode(m, pyramids, elevation); !st)
            return st;
    }
    if (auto st = createCities(); !st) return st;
    if (auto st = m_a.canopy.applyGround(m_imagery); !st) return st;
    for (Mode& m : m_modes)
        if (m.city) m.city->settings().view = city::cityViewFor(m_imagery);
    return Ok{};
}

Status BenchRun::createClipmapMode(Mode& m, const std::vector<ImagePyramid>& pyramids,
                                   const std::optional<ImagePyramid>& elevation) {
    ClipmapOptions co;
    co.size = m_a.clipmap.clipSize;
    co.uploadBudgetTexels = m_a.uploadBudget;
    co.minClipLevels = std::clamp(m_a.clipmap.clipLevels, 0, 16);
    auto c = ClipmapGL::create(pyramids, co);
    if (!c) return c.error();
    m.clipmap = std::move(*c);
    GeometryClipmapOptions go;
    go.n = m_a.clipmap.gridSize;
    auto r = ClipmapTerrainRendererGL::create(m_scene, *m.clipmap, elevation ? &*elevation : nullptr, go);
    if (!r) return r.error();
    m.clipRenderer = std::move(*r);
    // canopy=off in a comparison: no canopy at all (the leaf-on terrain); --canopy-layers off with --view
    // canopy: the canopy's ground without layers.
    const bool fromCompare = m.canopyLayers >= 0;
    const bool canopyView = m_imagery.view == ImageryView::Canopy;
    const int layers = fromCompare ? m.canopyLayers : (canopyView ? m_canopy.layers : 0);
    const bool wantCanopy = fromCompare ? layers > 0 : canopyView;
    m.canopyLayers = layers;
    return wantCanopy ? createCanopy(m, pyramids, layers) : Status(Ok{});
}

Status BenchRun::createCanopy(Mode& m, const std::vector<ImagePyramid>& pyramids, int layers) {
    auto hist = preparePairStats(m_scene, pyramids, m_cache);
    if (!hist) return hist.error();
    CanopyOptions opt;
    opt.params = m_canopy.params;
    opt.layers = std::max(1, layers);
    opt.onDemand = m.canopyLevelsRead ? m.canopyLevelsRead : m_canopy.levelsRead;
    opt.derivation = m.canopyDerivation.value_or(m_canopy.derivation);
    const SegmentationStats stats = statsFromHistograms(*hist, opt.params.method);
    if (m.canopyPyramid != false) {
        auto p = canopyPyramid(pyramids, opt, stats, m_cache, m.canopyPyramid == true);
        if (!p) return p.error();
        opt.precomputed = std::move(*p);
    }
    auto cc = CanopyClipmapGL::create(*m.clipmap, stats, opt);
    if (!cc) return cc.error();
    m.canopy = std::move(*cc);
    auto cr = CanopyRendererGL::create();
    if (!cr) return cr.error();
    m.canopyRenderer = std::move(*cr);
    m.clipRenderer->setCanopy(m.canopy.get());
    if (m_canopy.trunks && layers > 0) {
        auto tr = TrunksGL::create(m_scene, *m.clipmap, *m.canopy);
        if (!tr) return tr.error();
        m.trunks = std::move(*tr);
        m.canopy->keepLevelsFrom(m.trunks->level()); // the crown search reads its level whole
    }
    return Ok{};
}

// The city's tree, once for every mode that draws it.
Status BenchRun::createCities() {
    std::filesystem::path cityTree;
    for (Mode& m : m_modes) {
        if (!m.cityMode || !m.clipRenderer) continue;
        if (cityTree.empty()) {
            auto t = prepareCityTree(m_scene, m_cache, m_a.city.tree);
            if (!t) return t.error();
            cityTree = *t;
        }
        city::CitySettings cs;
        cs.mode = *m.cityMode;
        cs.capacityBytes = std::uint64_t(std::max(1.0, m_a.city.capacityMb) * 1048576.0);
        cs.tpp = m_a.city.tpp;
        cs.anisotropy = m.anisotropy;
        cs.upload = m.cityUpload;
        cs.occlusion = m.cityOcclusion;
        cs.flushFirst = m.cityFlush;
        cs.mapOcclusion = m.cityMapOcclusion;
        cs.blockMaps = m_a.city.blockMaps;
        cs.blockMapErrorPx = m_a.city.blockMapErrorPx;
        if (auto st = prepareCityBlockMaps(m_scene, cityTree, m_cache, cs); !st) return st.error();
        auto c = city::CityRendererGL::create(m_scene, cityTree.string(), cs);
        if (!c) return c.error();
        m.city = std::move(*c);
    }
    return Ok{};
}

// A damaged cache tile is never drawn nor measured: the run stops (benchCommand rebuilds and runs again).
void BenchRun::checkDamage(Mode& m) {
    if (!m_damaged.empty() || !m.clipmap) return;
    if (const auto& e = m.clipmap->readError()) m_damaged = e->message;
    else if (const auto g = m.clipRenderer->geometry().elevationReadError()) m_damaged = g->message;
    else if (m.canopy && !m.canopy->readError().empty()) m_damaged = m.canopy->readError();
    else if (m.city) m_damaged = m.city->readError();
}

// The last measured frame of each mode, as drawn: `last_frame_<mode>.png` (characters other than letters, digits,
// '.', '-' and '_' in the mode's label as '_'), so a run's pictures can be looked at and compared.
std::filesystem::path lastFrameFile(const std::filesystem::path& out, const std::string& label) {
    std::string name = label;
    for (char& c : name)
        if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '-' && c != '_') c = '_';
    return out / ("last_frame_" + name + ".png");
}

Status BenchRun::run(const CameraPath& path, const std::filesystem::path& out) {
    const auto terrain = [&](double x, double y) { return m_scene.terrainHeight(x, y); };
    const auto start = Clock::now();
    for (int i = 0; i < m_a.warmup; ++i)
        for (Mode& m : m_modes) frame(m, path.at(0.0, terrain), -1, false);
    if (!m_damaged.empty()) return Error{m_damaged};
    // Measuring starts from a fully loaded view, so uploads compare with the texels the path's moves expose.
    for (Mode& m : m_modes)
        if (m.clipmap) {
            if (!m.terrainOnly || m.city) m.clipmap->completeSynchronously();
            m.clipRenderer->completeGeometry();
            if (m.city) {
                m.city->complete(path.at(0.0, terrain), m_w, m_h);
                m.city->resetOcclusion(); // the warm-up's answers came from a view with less resident
            }
            checkDamage(m);
        }
    if (!m_damaged.empty()) return Error{m_damaged};
    // A city's modes then draw one frame at the path's start unmeasured: the warm-up drew what was resident then (in
    // blockmap mode no map yet), and the first draw with a program in a new GL state compiles it (llvmpipe: LLVM,
    // 200-300 ms for the BlockMaps' ray cast; Mesa keeps it on disk for later runs). Measured, that compile was the
    // first frame of every run after a shader change. Its occlusion answers are those of the completed view.
    if (m_a.warmup > 0)
        for (Mode& m : m_modes)
            if (m.city) frame(m, path.at(0.0, terrain), -1, false);
    if (!m_damaged.empty()) return Error{m_damaged};
    for (int f = 0; f < m_a.frames; ++f) {
        const Camera cam = path.at(double(f) / double(m_a.frames - 1), terrain);
        for (Mode& m : m_modes) {
            frame(m, cam, f, true); // interleaved: every mode sees the same load
            if (f + 1 == m_a.frames && m_damaged.empty())
                if (auto st = writeRgb(m_target, lastFrameFile(out, m.label)); !st) return st;
        }
        if (!m_damaged.empty()) return Error{m_damaged};
    }
    m_seconds = ms(Clock::now() - start) / 1000.0;
    return Ok{};
}

void BenchRun::frame(Mode& m, const Camera& cam, int frame, bool record) {
    FrameRow row;
    row.frame = frame;
    row.camera = cam;
    if (record && m.rows.empty() && m.clipmap) {
        m.clipmapTotalAtStart = m.clipmap->totalTexelsUploaded();
        m.elevationTotalAtStart = m.clipRenderer->geometry().totalTexelsUploaded();
    }
    const auto t0 = Clock::now();
    // GPU time from here: the frame's texture uploads are part of it.
    glBeginQuery(GL_TIME_ELAPSED, m_timer.id());
    if (record && !m_a.stages.empty()) gl::beginFrameStages(m_a.stages == "finish");
    ClipmapFrameStats cs, es;
    stream(m, cam, row, cs, es);
    row.streamMs = ms(Clock::now() - t0);
    draw(m, cam, row);
    if (record && !m_a.stages.empty()) {
        gl::markStage("unmarked"); // what the frame issued after its last mark
        row.stages = gl::endFrameStages();
    }
    glEndQuery(GL_TIME_ELAPSED);
    const auto t1 = Clock::now();
    glFinish();
    const auto t2 = Clock::now();
    GLuint64 ns = 0;
    glGetQueryObjectui64v(m_timer.id(), GL_QUERY_RESULT, &ns);
    if (!record) return;
    row.cpuMs = ms(t1 - t0);
    row.frameMs = ms(t2 - t0);
    row.gpuMs = double(ns) * 1e-6;
    // The commands were issued after t0 and had finished at t2 (the previous frame ended with glFinish), so
    // their GPU time cannot exceed t2 - t0. llvmpipe answers a process's very first time-elapsed query with
    // hours: such a result is unknown ("nan" in frames.csv, left out of the summary), not a figure.
    if (row.gpuMs > row.frameMs + 1.0) row.gpuMs = NAN;
    this->record(m, cam, row, cs, es);
}

// The frame's streaming: the imagery and elevation clipmaps' uploads, the canopy's derivation and trunk search.
void BenchRun::stream(Mode& m, const Camera& cam, FrameRow& row, ClipmapFrameStats& cs, ClipmapFrameStats& es) {
    if (m.clipmap) {
        // scene=terrain draws the relief without imagery: its imagery clipmap does not stream (unless a city's
        // roofs read it).
        if (!m.terrainOnly || m.city) {
            const ClipmapGeometry g = clipmapGeometry(m_scene, m.clipmap->schedule().layout());
            cs = m.clipmap->update(clipmapCentres(m_scene, cam, m_w, m_h, m.centers, g));
            gl::markStage("imagery_clipmap");
        }
        es = m.clipRenderer->updateGeometry(cam, m_h);
        gl::markStage("elevation_clipmap");
        // A damaged cache tile is never drawn nor measured: the run stops, the pyramid is rebuilt next time.
        checkDamage(m);
    }
    if (m.canopy) {
        // Upload-time derivation: only blocks newly resident; per-frame: everything resident, every frame.
        const CanopyFrameStats derived = m.perFrameSegmentation ? m.canopy->rederiveAll() : m.canopy->update();
        row.canopyBlocksDerived = derived.blocksDerived;
        row.canopyBlocksPending = derived.blocksPending;
        row.canopyBlocksUnread = derived.blocksUnread;
        row.canopyBlocksOnDemand = derived.blocksOnDemand;
        gl::markStage("canopy_derive");
        // Crown centres of the trunks: searched again when the searched level's derived blocks changed.
        if (m.trunks) row.trunkSearches = m.trunks->update() ? 1 : 0;
        gl::markStage("trunk_search");
    }
}

// The frame's draws: the terrain (or the canopy view over it), then the city; or the reference renderer.
void BenchRun::draw(Mode& m, const Camera& cam, FrameRow& row) {
    m_imagery.anisotropy = m.anisotropy;
    ImagerySettings im = m_imagery;
    im.path = m.terrainShading;
    if (m.clipmap && !m.canopy && im.view == ImageryView::Canopy) im.view = ImageryView::LeafOn; // canopy=off
    if (m.canopy) im.view = ImageryView::Canopy;
    if (m.terrainOnly) im.view = ImageryView::Relief;
    im.terrain = m.drawTerrain;
    CanopyRenderSettings modeCanopy = m_canopy;
    modeCanopy.trunks = m.trunks != nullptr;
    if (m.canopyDraw) modeCanopy.draw = *m.canopyDraw;
    const CanopyDrawSettings cd = canopyDrawSettings(m_scene, modeCanopy, im);
    if (m.canopy && m.canopyLayers > 0 && cd.crownBase <= 0.0)
        im.canopyBase = cd.darkest; // the ground draws layer 0 under the stacked ones
    if (!m.clipmap) {
        m.reference->render(cam, m_imagery.view == ImageryView::LeafOff ? Season::LeafOff : Season::LeafOn, m_target);
        return;
    }
    const bool stacked = m.canopy && m.canopyLayers > 0;
    const GeometryFrameStats drawn =
        stacked ? m.canopyRenderer->renderView(cam, *m.clipRenderer, im, *m.canopy, cd, m.trunks.get(), m_target)
                : m.clipRenderer->render(cam, im, m_target);
    if (!stacked) gl::markStage("terrain");
    row.drawCalls = drawn.drawCalls;
    row.triangles = drawn.triangles;
    if (m.city) {
        const auto c0 = Clock::now();
        m.city->update(cam, m_w, m_h);
        row.cityUpdateMs = ms(Clock::now() - c0);
        gl::markStage("city_paging");
        row.city = m.city->draw(cam, m.clipRenderer.get(), m_target);
        gl::markStage("city_draw");
        checkDamage(m); // an atlas that did not decode is found when uploaded, in draw()
        row.cityCpuMs = ms(Clock::now() - c0);
        row.drawCalls += row.city.drawCalls;
        row.triangles += row.city.triangles;
    }
}

// A measured frame's counters (its times are in `row` already).
void BenchRun::record(Mode& m, const Camera& cam, FrameRow& row, const ClipmapFrameStats& cs,
                      const ClipmapFrameStats& es) {
    if (!m.clipmap) row.triangles = m.reference->stats().triangles;
    row.texelsUploaded = cs.texelsUploaded;
    row.exposedTexels = cs.exposedTexels;
    row.blocksMissing = cs.blocksMissing;
    row.residentBytes = (m.clipmap ? m.clipmap->residentBytes() : 0) + (m.canopy ? m.canopy->residentBytes() : 0);
    row.loaderCacheBytes = m.clipmap ? m.clipmap->loaderCacheBytes() + m.clipRenderer->geometry().loaderCacheBytes() : 0;
    row.elevationTexelsUploaded = es.texelsUploaded;
    row.elevationResidentBytes = m.clipRenderer ? m.clipRenderer->geometry().residentBytes() : 0;
    row.rssBytes = residentSetBytes();
    heapBytes(row.heapInUseBytes, row.heapMappedBytes);
    if (m.clipmap && m_a.coverageEvery > 0 && row.frame % m_a.coverageEvery == 0)
        row.coverage = m.clipRenderer->measureLevels(cam, m_scratch).coverage;
    row.runOrder = m_recorded++;
    m.rows.push_back(row);
}

// --stages: each stage's CPU time and GPU wait per frame (a stage marked twice in a frame counted once, summed), in
// the order the first frame marked them.
nlohmann::json stageFigures(const Mode& m) {
    std::vector<std::string> order;
    std::map<std::string, std::pair<std::vector<double>, std::vector<double>>> per;
    for (const FrameRow& r : m.rows) {
        std::map<std::string, std::pair<double, double>> frame;
        for (const gl::StageTime& t : r.stages) {
            if (per.try_emplace(t.name).second) order.push_back(t.name);
            frame[t.name].first += t.cpuMs;
            frame[t.name].second += t.waitMs;
        }
        for (auto& [name, v] : frame) {
            per[name].first.push_back(v.first);
            per[name].second.push_back(v.second);
        }
    }
    if (order.empty()) return nullptr;
    nlohmann::json out = nlohmann::json::array();
    for (const std::string& name : order)
        out.push_back({{"stage", name}, {"cpu_ms", figure(per[name].first)}, {"wait_ms", figure(per[name].second)}});
    return out;
}

// stages.csv (--stages): one row per stage of every measured frame of every mode.
Status writeStagesCsv(const std::filesystem::path& file, const std::vector<Mode>& modes) {
    std::ostringstream csv;
    csv << "mode,frame,stage,cpu_ms,wait_ms\n";
    for (const Mode& m : modes)
        for (const FrameRow& r : m.rows)
            for (const gl::StageTime& t : r.stages) {
                char line[256];
                std::snprintf(line, sizeof line, "%s,%d,%s,%.4f,%.4f\n", m.label.c_str(), r.frame, t.name.c_str(),
                              t.cpuMs, t.waitMs);
                csv << line;
            }
    std::string err;
    if (!writeTextAtomic(file, csv.str(), err)) return Error{file.string() + ": " + err};
    return Ok{};
}

// frames.csv: one row per measured frame of every mode.
Status writeFramesCsv(const std::filesystem::path& file, const std::vector<Mode>& modes) {
    std::ostringstream csv;
    csv << "mode,frame,x,y,z,yaw,pitch,cpu_ms,gpu_ms,frame_ms,draw_calls,triangles,texels_uploaded,exposed_texels,"
           "blocks_missing,resident_texture_bytes,loader_cache_bytes,rss_bytes,coverage,city_atlas_nodes,"
           "city_texture_binds,city_draw_calls,city_triangles,city_blocks_resident,city_resident_bytes,"
           "city_loader_queue,city_coarser_than_wanted,heap_in_use_bytes,heap_mapped_bytes,canopy_blocks_derived,"
           "trunk_searches,city_cpu_ms,city_occluded_nodes,city_occlusion_queries,city_occlusion_waits,"
           "elevation_texels_uploaded,elevation_resident_bytes,run_order,city_allocated_bytes,city_evicted_blocks,"
           "canopy_blocks_pending,canopy_blocks_unread,canopy_blocks_on_demand,city_update_ms,city_upload_ms,"
           "city_uploaded_bytes,city_wait_ms,stream_ms,city_blockmaps,city_blockmaps_not_resident,city_blockmap_pool_bytes,"
           "city_blockmap_moved_bytes,city_requested_bytes,city_ideal_bytes\n";
    for (const Mode& m : modes)
        for (const FrameRow& r : m.rows) {
            char line[640];
            std::snprintf(line, sizeof line,
                          "%s,%d,%.3f,%.3f,%.3f,%.3f,%.3f,%.4f,%.4f,%.4f,%d,%lld,%lld,%lld,%d,%lld,%lld,%lld,%s,"
                          "%d,%d,%d,%lld,%zu,%llu,%zu,%d,%lld,%lld,%d,%d,%.4f,%d,%d,%d,%lld,%lld,%d,%llu,%zu,%d,%d,%d,%.4f,%.4f,"
                          "%llu,%.4f,%.4f,%d,%d,%llu,%llu,%llu,%llu\n",
                          m.label.c_str(), r.frame, r.camera.position.x, r.camera.position.y, r.camera.position.z,
                          r.camera.yawDeg, r.camera.pitchDeg, r.cpuMs, r.gpuMs, r.frameMs, r.drawCalls,
                          (long long)r.triangles, (long long)r.texelsUploaded, (long long)r.exposedTexels,
                          r.blocksMissing, (long long)r.residentBytes, (long long)r.loaderCacheBytes,
                          (long long)r.rssBytes, std::isfinite(r.coverage) ? std::to_string(r.coverage).c_str() : "",
                          r.city.atlasNodes, r.city.textureBinds, r.city.drawCalls, (long long)r.city.triangles,
                          r.city.blocksResident, (unsigned long long)r.city.residentBytes, r.city.loaderQueue,
                          r.city.coarserThanWanted, (long long)r.heapInUseBytes, (long long)r.heapMappedBytes,
                          r.canopyBlocksDerived, r.trunkSearches, r.cityCpuMs, r.city.occludedNodes,
                          r.city.occlusionQueries, r.city.occlusionWaits, (long long)r.elevationTexelsUploaded,
                          (long long)r.elevationResidentBytes, r.runOrder,
                          (unsigned long long)r.city.allocatedBytes, r.city.evictedBlocks, r.canopyBlocksPending,
                          r.canopyBlocksUnread, r.canopyBlocksOnDemand, r.cityUpdateMs, r.city.uploadMs,
                          (unsigned long long)r.city.uploadedBytes, r.city.waitMs, r.streamMs, r.city.blockMaps,
                          r.city.blockMapsNotResident, (unsigned long long)r.city.blockMapPoolBytes,
                          (unsigned long long)r.city.blockMapMovedBytes, (unsigned long long)r.city.requestedBytes,
                          (unsigned long long)r.city.idealBytes);
            csv << line;
        }
    std::string err;
    if (!writeTextAtomic(file, csv.str(), err)) return Error{file.string() + ": " + err};
    return Ok{};
}

// summary.json's run description: the device, the scene, the path and every setting.
nlohmann::json summaryHead(const gl::ContextInfo& device, const Scene& scene, const BenchSettings& a, double seconds) {
    return {{"device", {{"platform", device.platform}, {"renderer", device.renderer}, {"version", device.version}}},
            {"scene", scene.sources.manifest.empty() ? scene.sources.leafon.describe() : scene.sources.manifest.string()},
            {"image_size", {scene.leafon.info.width, scene.leafon.info.height}},
            {"size", {a.width, a.height}},
            {"path", a.path},
            {"frames", a.frames},
            {"warmup", a.warmup},
            {"settings",
             {{"clip_size", a.clipmap.clipSize},
              {"upload_budget_texels", a.uploadBudget},
              {"view", a.imagery.view},
              {"aniso", a.imagery.aniso},
              {"clip_levels_min", a.clipmap.clipLevels},
              {"grid_size", a.clipmap.gridSize},
              {"coverage_every", a.coverageEvery},
              {"canopy_layers", a.canopy.layers},
              {"segmentation_method", a.canopy.method},
              {"segmentation_k", a.canopy.k},
              {"trunks", a.canopy.trunks},
              {"canopy_draw", a.canopy.draw},
              {"ground_under_canopy", a.canopy.groundUnder},
              {"ground_elsewhere", a.canopy.groundElsewhere},
              {"city_upload", a.city.upload},
              {"city_occlusion", a.city.occlusion},
              {"city_map_occlusion", a.city.mapOcclusion},
              {"terrain", a.imagery.terrain},
              {"terrain_shading", a.imagery.terrainShading},
              // what auto chose on this device (a compare's modes name their own)
              {"terrain_shading_resolved",
               terrainShadingName(resolveTerrainShading(
                   parseTerrainShading(a.imagery.terrainShading).value_or(TerrainShading::Auto), device.renderer))},
              {"renderer", a.clipmap.renderer},
              {"centers", a.clipmap.centers},
              {"seed", a.seed},
              {"compare", a.compare},
              {"city", a.city.mode},
              {"city_tree", a.city.tree},
              {"city_capacity_mb", a.city.capacityMb},
              {"city_tpp", a.city.tpp},
              {"tree_height_m", scene.sources.treeHeightM}}},
            {"wall_seconds", seconds}};
}

nlohmann::json jsonNumber(double x) { return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr); }

// One mode's figures over its measured frames: summary.json's entry, and what the table, compare.json and the plot
// show of it.
struct ModeFigures {
    nlohmann::json summary;
    std::vector<double> frame, gpu, coverage, texels;
    double median = NAN, coverageMean = NAN, uploadRatio = NAN;
    std::int64_t uploaded = 0;
};

ModeFigures modeFigures(const Mode& m) {
    ModeFigures f;
    std::vector<double> cpu, streamCpu, rss, resident, drawCalls, triangles, loaderCache, elevTexels, elevResident;
    std::int64_t exposed = 0, elevUploaded = 0;
    int canopyBlocks = 0, trunkSearches = 0, covN = 0;
    double covSum = 0.0;
    for (const FrameRow& r : m.rows) {
        drawCalls.push_back(double(r.drawCalls));
        triangles.push_back(double(r.triangles));
        loaderCache.push_back(double(r.loaderCacheBytes));
        elevTexels.push_back(double(r.elevationTexelsUploaded));
        elevResident.push_back(double(r.elevationResidentBytes));
        elevUploaded += r.elevationTexelsUploaded;
        cpu.push_back(r.cpuMs);
        streamCpu.push_back(r.streamMs);
        f.gpu.push_back(r.gpuMs);
        f.frame.push_back(r.frameMs);
        f.texels.push_back(double(r.texelsUploaded));
        f.coverage.push_back(r.coverage);
        rss.push_back(double(r.rssBytes));
        resident.push_back(double(r.residentBytes));
        f.uploaded += r.texelsUploaded;
        exposed += r.exposedTexels;
        canopyBlocks += r.canopyBlocksDerived;
        trunkSearches += r.trunkSearches;
        if (std::isfinite(r.coverage)) {
            covSum += r.coverage;
            ++covN;
        }
    }
    const int layers = m.clipmap ? m.clipmap->layers() : 1;
    f.uploadRatio = exposed > 0 ? double(f.uploaded) / double(layers) / double(exposed) : NAN;
    f.coverageMean = covN ? covSum / covN : NAN;
    f.median = percentile(f.frame, 50);
    f.summary = {{"frame_ms", figure(f.frame)},
                 {"cpu_ms", figure(cpu)},
                 {"stream_ms", figure(streamCpu)},
                 {"gpu_ms", figure(f.gpu)},
                 {"texels_uploaded", figure(f.texels)},
                 {"draw_calls", figure(drawCalls)},
                 {"triangles", figure(triangles)},
                 {"loader_cache_bytes", figure(loaderCache)},
                 {"elevation_texels_uploaded", figure(elevTexels)},
                 {"elevation_resident_bytes", figure(elevResident)},
                 {"coverage", figure(f.coverage)},
                 {"coverage_mean", jsonNumber(f.coverageMean)},
                 {"rss_bytes", figure(rss)},
                 {"resident_texture_bytes", figure(resident)},
                 {"rss_bytes_start", m.rows.front().rssBytes},
                 {"rss_bytes_end", m.rows.back().rssBytes},
                 {"heap_in_use_bytes_start", m.rows.front().heapInUseBytes},
                 {"heap_in_use_bytes_end", m.rows.back().heapInUseBytes},
                 {"heap_mapped_bytes_end", m.rows.back().heapMappedBytes},
                 {"resident_texture_bytes_start", m.rows.front().residentBytes},
                 {"resident_texture_bytes_end", m.rows.back().residentBytes},
                 {"worst_frame_over_median", jsonNumber(percentile(f.frame, 100) / f.median)},
                 // Where the canopy layer's clip-level blocks come from: read from the layer `prepare` made, derived
                 // on the loader's workers, or derived on the GPU; null without a canopy.
                 {"canopy_source", !m.canopy ? nlohmann::json(nullptr)
                                   : m.canopy->readsPrecomputed() ? nlohmann::json("precomputed")
                                   : m.canopy->derivesOnCpu()     ? nlohmann::json("cpu")
                                                                  : nlohmann::json("gpu")},
                 {"city", m.city ? cityFigures(m) : nlohmann::json(nullptr)},
                 {"stages", stageFigures(m)},
                 {"totals",
                  {{"texels_uploaded", f.uploaded},
                   {"exposed_texels_per_layer", exposed},
                   {"upload_over_geometric_minimum", jsonNumber(f.uploadRatio)},
                   {"triangles_per_frame", m.rows.front().triangles},
                   // The clipmaps' own accounting over the recorded frames (the sums of frames.csv's columns must
                   // equal these).
                   {"clipmap_reported_texels_uploaded",
                    m.clipmap ? m.clipmap->totalTexelsUploaded() - m.clipmapTotalAtStart : 0},
                   {"elevation_texels_uploaded", elevUploaded},
                   {"elevation_reported_texels_uploaded",
                    m.clipRenderer ? m.clipRenderer->geometry().totalTexelsUploaded() - m.elevationTotalAtStart : 0},
                   {"canopy_blocks_derived", canopyBlocks},
                   {"trunk_searches", trunkSearches},
                   // Streamed seasons (--stream): blocks whose tiles failed (drawn from coarser levels, asked again).
                   {"stream_errors", m.clipmap ? m.clipmap->streamErrors() : 0},
                   {"last_stream_error", m.clipmap ? m.clipmap->lastStreamError() : std::string()}}}};
    return f;
}

// summary.json, compare.json (several modes) and plot.png; the printed table in the result.
Status writeSummary(const std::filesystem::path& out, nlohmann::json summary, const std::vector<Mode>& modes,
                    BenchResult& result) {
    nlohmann::json compare = nlohmann::json::array();
    double baseMedian = NAN;
    std::vector<PlotPanel> panels(3);
    panels[0].title = "frame time (ms)";
    panels[1].title = "coverage";
    panels[1].yMin = 0.0;
    panels[1].yMax = 1.0;
    panels[2].title = "texels uploaded per frame";
    char line[256];
    std::snprintf(line, sizeof line, "%-24s %12s %10s %10s %10s %12s %10s\n", "mode", "median ms", "p95 ms", "max ms",
                  "ratio", "coverage", "upload/min");
    result.table = line;
    for (const Mode& m : modes) {
        ModeFigures f = modeFigures(m);
        if (!std::isfinite(baseMedian)) baseMedian = f.median;
        summary["modes"][m.label] = std::move(f.summary);
        compare.push_back({{"mode", m.label},
                           {"median_frame_ms", f.median},
                           {"ratio_to_first", f.median / baseMedian},
                           {"median_gpu_ms", jsonNumber(percentile(f.gpu, 50))},
                           {"coverage_mean", jsonNumber(f.coverageMean)},
                           {"texels_uploaded", f.uploaded}});
        std::snprintf(line, sizeof line, "%-24s %12.2f %10.2f %10.2f %10.3f %12.4f %10.3f\n", m.label.c_str(), f.median,
                      percentile(f.frame, 95), percentile(f.frame, 100), f.median / baseMedian, f.coverageMean,
                      f.uploadRatio);
        result.table += line;
        result.modes.push_back({m.label, f.median, percentile(f.frame, 95), percentile(f.frame, 100),
                                f.median / baseMedian, f.coverageMean, f.uploadRatio});
        panels[0].series.push_back({m.label, f.frame});
        panels[1].series.push_back({m.label, f.coverage});
        panels[2].series.push_back({m.label, f.texels});
    }
    std::string err;
    if (!writeTextAtomic(out / "summary.json", summary.dump(2) + "\n", err))
        return Error{(out / "summary.json").string() + ": " + err};
    if (modes.size() > 1 && !writeTextAtomic(out / "compare.json", compare.dump(2) + "\n", err))
        return Error{(out / "compare.json").string() + ": " + err};
    return writeLinePlot(out / "plot.png", panels, "frame");
}

} // namespace

Result<BenchResult> runBench(const Scene& scene, const BenchSettings& a, const std::filesystem::path& out) {
    auto canopy = a.canopy.settings();
    if (!canopy) return canopy.error();
    const auto view = parseImageryView(a.imagery.view);
    if (!view)
        return Error{"--view '" + a.imagery.view + "': expected leafon|leafoff|blend|swipe|lod|wireframe|levels|relief|canopy"};
    if (auto st = a.clipmap.check(); !st) return st.error();
    if (a.frames < 2) return Error{"--frames must be at least 2"};
    auto modes = parseModes(a);
    if (!modes) return modes.error();
    const auto terrain = [&](double x, double y) { return scene.terrainHeight(x, y); };
    PathScene ps{scene.localMin, scene.localMax, terrain};
    std::error_code ec;
    auto path = std::filesystem::exists(a.path, ec) ? CameraPath::fromJson(a.path) : CameraPath::named(a.path, ps, a.seed);
    if (!path) return path.error();
    std::filesystem::create_directories(out, ec);
    if (ec) return Error{out.string() + ": cannot create folder (" + ec.message() + ")"};
    const std::filesystem::path cache = a.cacheDir.empty() ? defaultCacheDir() : a.cacheDir;
    std::array<std::vector<ImagePyramid>, 2> pyramids;
    std::optional<ImagePyramid> elevation;
    if (auto st = BenchRun::prepareInputs(scene, *modes, cache, pyramids, elevation); !st) return st.error();

    auto ctx = gl::createHeadlessContext();
    if (!ctx) return ctx.error();
    if (auto st = gl::checkFramebufferSize((*ctx)->info(), a.width, a.height, "--size"); !st) return st.error();
    // The modes' GL objects must die while the context lives (it was created after them).
    struct ReleaseFirst {
        std::vector<Mode>& modes;
        ~ReleaseFirst() { modes.clear(); }
    } releaseFirst{*modes};
    const int glErrors = gl::debugErrorCount();
    BenchRun run(scene, a, *modes, *canopy, *view, cache);
    if (auto st = run.createRenderers(pyramids, elevation); !st) return st.error();
    // Streamed seasons: the tiles fetched during the run against the tiles the blocks asked for needed.
    const bool streams = !pyramids[1].empty();
    resetStreamTileCount();
    const web::TileFetchCounter fetched(cache / "web" / "tiles");
    if (auto st = run.run(*path, out); !st) return st.error(); // a damaged tile: the command rebuilds and runs again
    nlohmann::json streamFigures = nullptr;
    if (streams) {
        const StreamTileCount need = streamTileCount();
        const web::TileFetchCounter::Count got = fetched.fetched();
        streamFigures = {{"tiles_needed", need.tilesNeeded},
                         {"regions_read", need.regionsRead},
                         {"tiles_fetched", got.tiles},
                         {"bytes_fetched", got.bytes},
                         {"fetched_over_needed",
                          need.tilesNeeded > 0 ? nlohmann::json(double(got.tiles) / double(need.tilesNeeded))
                                               : nlohmann::json(nullptr)},
                         // The measure in bytes: fetched against the bytes of the tiles needed (those in
                         // the disk cache; the others counted apart).
                         {"bytes_needed", need.bytesNeeded},
                         {"tiles_needed_not_cached", need.tilesNotCached},
                         {"bytes_fetched_over_needed",
                          need.bytesNeeded > 0 ? nlohmann::json(double(got.bytes) / double(need.bytesNeeded))
                                               : nlohmann::json(nullptr)}};
    }
    if (const std::string e = gl::drainErrors(); !e.empty() || gl::debugErrorCount() != glErrors)
        return Error{"OpenGL error during the benchmark " + e};

    if (auto st = writeFramesCsv(out / "frames.csv", *modes); !st) return st.error();
    if (!a.stages.empty())
        if (auto st = writeStagesCsv(out / "stages.csv", *modes); !st) return st.error();
    BenchResult result;
    result.device = (*ctx)->info().platform + ": " + (*ctx)->info().renderer;
    result.seconds = run.seconds();
    nlohmann::json head = summaryHead((*ctx)->info(), scene, a, run.seconds());
    // The streamed levels over the run (warm-up included): the service tiles the blocks read needed (the geometric
    // minimum), the regions read, and the tiles and bytes the disk cache gained (fetched from the service).
    head["stream"] = std::move(streamFigures);
    if (auto st = writeSummary(out, std::move(head), *modes, result); !st)
        return st.error();
    return result;
}

} // namespace seasonview::app
