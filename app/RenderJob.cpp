#include "RenderJob.h"

#include "CanopyClipmapGL.h"
#include "CanopyRendererGL.h"
#include "TrunksGL.h"

#include "DepthAccuracy.h"
#include "ElevationPyramid.h"

#include "AtomicFile.h"
#include "Commands.h"
#include "gl/GlDebug.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace seasonview::app {

void SceneArgs::addTo(CLI::App& cmd, bool withDem) {
    cmd.add_option("scene", manifest, "Scene manifest (scene.json); or give --leafon/--leafoff");
    cmd.add_option("--leafon", leafon,
                   "Leaf-on (summer) imagery, 8- or 16-bit RGB(A) in any format and CRS GDAL reads: a file, a folder "
                   "of tiles, a glob or a VRT (several for a mosaic)")
        ->expected(1, -1);
    cmd.add_option("--leafoff", leafoff,
                   "Leaf-off (winter) imagery, as --leafon; any grid, resolution and CRS (warped onto the working "
                   "grid)")
        ->expected(1, -1);
    if (withDem) {
        cmd.add_option("--dem", dem,
                       "Elevation (metres or feet) in any format and CRS: a file, folder, glob or VRT of tiles; flat "
                       "without")
            ->expected(1, -1);
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
                   "Working grid's extent XMIN,YMIN,XMAX,YMAX in its CRS (default: the union of both seasons)");
    cmd.add_option("--resampling", resampling,
                   "How seasons are warped onto the working grid: auto|near|bilinear|cubic|average|lanczos (auto: "
                   "near on the grid's lattice, average where a season is 1.5x finer, else bilinear)");
    cmd.add_option("--stretch", stretch,
                   "Display (and segmentation) colour: auto (16-bit through a per-band 0.5-99.5 % stretch, 8-bit as "
                   "it is), percentile (the stretch for 8-bit too: 8-bit radiometric data such as scaled reflectance), "
                   "none");
    cmd.add_option("--cache", cache, "Cache folder (default $SEASONVIEW_CACHE or ~/.cache/seasonview)");
}

std::filesystem::path SceneArgs::cacheDir() const {
    return cache.empty() ? defaultCacheDir() : std::filesystem::path(cache);
}

namespace {

SourceList listOf(const std::vector<std::string>& values) {
    SourceList l;
    for (const std::string& v : values) l.items.emplace_back(v);
    return l;
}

} // namespace

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
            return Error{"--extent '" + extent + "': expected XMIN,YMIN,XMAX,YMAX in the grid's CRS"};
        src.grid.extent = e;
    }
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

Camera overviewCamera(const Scene& scene, double aspect) {
    Camera c;
    const glm::dvec2 centre = (scene.localMin + scene.localMax) * 0.5;
    const glm::dvec2 half = (scene.localMax - scene.localMin) * 0.5;
    const double t = std::tan(c.fovYDeg * 0.5 * 3.14159265358979323846 / 180.0);
    const double dist = std::max(half.y / t, half.x / (t * aspect)) * 1.02;
    const double top = scene.elevation ? scene.elevation->maxHeight : 0.0;
    c.position = {centre.x, centre.y, top + dist};
    c.yawDeg = 0.0;
    c.pitchDeg = -90.0;
    return c;
}

Camera obliqueCamera(const Scene& scene, double yawDeg, double pitchDeg, double distanceFraction) {
    Camera c;
    const glm::dvec2 centre = (scene.localMin + scene.localMax) * 0.5;
    const double size = glm::length(scene.localMax - scene.localMin);
    c.yawDeg = yawDeg;
    c.pitchDeg = pitchDeg;
    const double ground = scene.terrainHeight(centre.x, centre.y);
    const double dist = size * distanceFraction;
    c.position = glm::dvec3(centre, ground) - c.forward() * dist;
    // Keep the camera above the terrain under it.
    c.position.z = std::max(c.position.z, scene.terrainHeight(c.position.x, c.position.y) + 20.0);
    return c;
}

Status checkImageOutput(const std::filesystem::path& out) {
    std::string ext = out.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char ch) { return char(std::tolower(ch)); });
    if (ext != ".png" && ext != ".tif" && ext != ".tiff")
        return fileError(out.string(), "output must be a .png or .tif image");
    std::error_code ec;
    const std::filesystem::path dir = out.parent_path();
    if (!dir.empty() && !std::filesystem::is_directory(dir, ec))
        return fileError(out.string(), "output folder " + dir.string() + " does not exist");
    return Ok{};
}

bool rebuildingDamaged(const std::string& message, const std::filesystem::path& cacheDir) {
    if (!invalidateDamagedPyramid(message, cacheDir)) return false;
    std::printf("note: %s: damaged in the cache; its pyramid is rebuilt from the source\n", message.c_str());
    std::fflush(stdout);
    return true;
}

namespace {

Result<std::vector<ImagePyramid>> preparePyramidsOnce(const Scene& scene, const std::filesystem::path& cacheDir,
                                                      std::vector<ImagePyramid>& out) {
    out.clear();
    const std::pair<const char*, const ImageryLayer*> layers[] = {{"leafon", &scene.leafon}, {"leafoff", &scene.leafoff}};
    for (const auto& [name, layer] : layers) {
        PrepareOptions o;
        o.cacheDir = cacheDir;
        o.progress = terminalProgress(name);
        auto report = preparePyramid(*layer, o);
        if (!report) return report.error();
        if (report->built) {
            std::printf("prepared %s pyramid in %.2f s (%s)\n", name, report->seconds, report->reason.c_str());
            std::fflush(stdout);
        }
        out.push_back(std::move(report->pyramid));
    }
    if (auto stats = preparePairStats(scene, out, cacheDir); !stats) return stats.error();
    return out;
}

} // namespace

Result<std::vector<ImagePyramid>> preparePyramids(const Scene& scene, const std::filesystem::path& cacheDir) {
    std::vector<ImagePyramid> pyramids;
    auto first = preparePyramidsOnce(scene, cacheDir, pyramids);
    if (first) return first;
    // A level file that does not decode (damaged in the cache: the pair statistics read every tile of level 0):
    // rebuilt from the source, once.
    if (!rebuildingDamaged(first.message(), cacheDir)) return first;
    return preparePyramidsOnce(scene, cacheDir, pyramids);
}

std::optional<std::array<std::filesystem::path, 2>> levelZeroOf(const Scene& scene,
                                                               const std::vector<ImagePyramid>& pyramids) {
    if (!scene.warped()) return std::nullopt;
    assert(pyramids.size() == 2 && "levelZeroOf(): the scene's two prepared pyramids");
    return std::array<std::filesystem::path, 2>{pyramids[0].levels[0].file, pyramids[1].levels[0].file};
}

Result<SegmentationHistograms> preparePairStats(const Scene& scene, const std::vector<ImagePyramid>& pyramids,
                                                const std::filesystem::path& cacheDir) {
    assert(pyramids.size() == 2 && pyramids[0].width() == scene.leafon.info.width &&
           pyramids[0].height() == scene.leafon.info.height &&
           "preparePairStats(): the leaf-on and leaf-off pyramids of the scene");
    (void)scene; // only checked: the pyramids' source keys already name both layers and their stretches
    PairHistogramsReport report;
    auto histograms = preparePairHistograms(pyramids[0], pyramids[1], cacheDir, terminalProgress("pair stats"), &report);
    if (!histograms) return histograms.error();
    if (report.built) {
        std::printf("prepared pair statistics in %.2f s (%s)\n", report.seconds, report.reason.c_str());
        std::fflush(stdout);
    }
    return histograms;
}

Result<std::optional<ImagePyramid>> prepareElevation(const Scene& scene, const std::filesystem::path& cacheDir) {
    if (!scene.elevation) return std::optional<ImagePyramid>();
    PrepareOptions o;
    o.cacheDir = cacheDir;
    o.progress = terminalProgress("elevation");
    const PyramidSource source = elevationPyramidSource(scene, elevationGrid(scene));
    auto report = preparePyramid(source, o);
    if (!report) return report.error();
    if (report->built) {
        std::printf("prepared elevation pyramid in %.2f s (%s)\n", report->seconds, report->reason.c_str());
        std::fflush(stdout);
    }
    return std::optional<ImagePyramid>(std::move(report->pyramid));
}

ClipmapGeometry clipmapGeometry(const Scene& scene, const ClipmapLayout& layout) {
    ClipmapGeometry g;
    g.levels = layout.clipLevels();
    g.size = layout.size;
    g.texelSize0 = scene.gsd;
    return g;
}

std::vector<glm::dvec2> clipmapCentres(const Scene& scene, const Camera& camera, int width, int height,
                                       CenterPlacement placement, const ClipmapGeometry& geometry) {
    ViewSetup v;
    v.camera = camera;
    v.width = width;
    v.height = height;
    v.aspect = double(width) / double(height);
    v.groundHeight = scene.terrainHeight(camera.position.x, camera.position.y);
    std::vector<glm::dvec2> px;
    for (const glm::dvec2& c : placeCenters(placement, v, geometry)) px.push_back(scene.localToImagePixel(c));
    return px;
}

Status writeRgb(const gl::RenderTarget& target, const std::filesystem::path& out) {
    const std::vector<std::uint8_t> rgba = target.readRgba();
    const size_t n = size_t(target.width()) * size_t(target.height());
    std::vector<std::uint8_t> rgb(n * 3);
    for (size_t i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c) rgb[i * 3 + size_t(c)] = rgba[i * 4 + size_t(c)];
    return writeImageAtomic(out, rgb.data(), target.width(), target.height(), 3);
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

Status parseCanopyDrawArg(const std::string& value, CanopyRenderSettings& settings) {
    if (value != "layers" && value != "march") return Error{"--canopy-draw '" + value + "': expected layers|march"};
    settings.draw = value == "layers" ? CanopyDrawMode::Layers : CanopyDrawMode::March;
    return Ok{};
}

CanopyDrawSettings canopyDrawSettings(const Scene& scene, const CanopyRenderSettings& canopy,
                                      const ImagerySettings& imagery) {
    CanopyDrawSettings cd;
    cd.mode = canopy.draw;
    cd.treeHeight = scene.sources.treeHeightM;
    cd.anisotropy = imagery.anisotropy;
    cd.shading = imagery.shading;
    cd.crownBase = canopy.trunks ? canopy.crownBaseFraction * cd.treeHeight : 0.0;
    cd.scene = &scene;
    return cd;
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

namespace {

/// renderStills once. A pyramid tile that cannot be read stops it: nothing is written for the still.
Result<gl::ContextInfo> renderStillsOnce(const Scene& scene, int width, int height, const std::vector<StillRequest>& stills,
                                         const RenderSettings& settings) {
    std::vector<ImagePyramid> pyramids;
    if (settings.renderer == RendererKind::Clipmap || scene.warped()) { // the reference reads warped seasons' level 0
        auto p = preparePyramids(scene, settings.cacheDir);
        if (!p) return p.error();
        pyramids = std::move(*p);
    }
    auto ctx = settings.windowed ? gl::createWindowContext(width, height, "seasonview", false)
                                 : gl::createHeadlessContext();
    if (!ctx) return ctx.error();
    if (auto st = gl::checkFramebufferSize((*ctx)->info(), width, height, "--size"); !st) return st.error();
    const int errorsBefore = gl::debugErrorCount();
    gl::RenderTarget target(width, height);
    auto checkGl = [&](const std::filesystem::path& out) -> Status {
        if (const std::string e = gl::drainErrors(); !e.empty() || gl::debugErrorCount() != errorsBefore)
            return Error{"OpenGL error while rendering " + out.string() + (e.empty() ? "" : ": " + e)};
        return Ok{};
    };
    auto present = [&] {
        if (!settings.windowed) return;
        int fw = 0, fh = 0;
        (*ctx)->framebufferSize(fw, fh);
        target.blitToDefault(fw, fh);
        (*ctx)->swapBuffers();
    };
    if (settings.renderer == RendererKind::Reference) {
        ReferenceOptions options;
        options.anisotropy = settings.referenceAnisotropy;
        options.levelZero = levelZeroOf(scene, pyramids);
        auto renderer = ReferenceRendererGL::create(scene, options);
        if (!renderer) return renderer.error();
        for (const StillRequest& s : stills) {
            const ImageryView v = s.imagery.view;
            if (v != ImageryView::LeafOn && v != ImageryView::LeafOff)
                return Error{std::string("--view ") + imageryViewName(v) + " needs --renderer clipmap"};
            (*renderer)->render(s.camera, v == ImageryView::LeafOn ? Season::LeafOn : Season::LeafOff, target);
            if (auto st = checkGl(s.out); !st) return st.error();
            if (auto st = writeRgb(target, s.out); !st) return st.error();
            present();
        }
        return (*ctx)->info();
    }
    auto clipmap = ClipmapGL::create(pyramids, settings.clipmap);
    if (!clipmap) return clipmap.error();
    auto elevation = prepareElevation(scene, settings.cacheDir);
    if (!elevation) return elevation.error();
    auto renderer = ClipmapTerrainRendererGL::create(scene, **clipmap, *elevation ? &**elevation : nullptr,
                                                     settings.geometry);
    if (!renderer) return renderer.error();
    const ClipmapGeometry geometry = clipmapGeometry(scene, (*clipmap)->schedule().layout());
    // The canopy view's derived layer and stacked layers, made when a still asks for them.
    std::unique_ptr<CanopyClipmapGL> canopy;
    std::unique_ptr<CanopyRendererGL> canopyRenderer;
    std::unique_ptr<TrunksGL> trunks;
    if (std::any_of(stills.begin(), stills.end(), [](const StillRequest& s) { return s.imagery.view == ImageryView::Canopy; })) {
        auto hist = preparePairStats(scene, pyramids, settings.cacheDir);
        if (!hist) return hist.error();
        CanopyOptions co;
        co.params = settings.canopy.params;
        co.layers = std::max(1, settings.canopy.layers);
        auto c = CanopyClipmapGL::create(**clipmap, statsFromHistograms(*hist, co.params.method), co);
        if (!c) return c.error();
        canopy = std::move(*c);
        auto cr = CanopyRendererGL::create();
        if (!cr) return cr.error();
        canopyRenderer = std::move(*cr);
        (*renderer)->setCanopy(canopy.get());
        if (settings.canopy.trunks && settings.canopy.layers > 0) {
            auto t = TrunksGL::create(scene, **clipmap, *canopy);
            if (!t) return t.error();
            trunks = std::move(*t);
        }
    }
    std::unique_ptr<gl::RenderTarget> scratch;
    std::unique_ptr<ReferenceRendererGL> reference;
    std::unique_ptr<city::CityRendererGL> cityRenderer;
    if (settings.city) {
        city::CitySettings cs = *settings.city;
        cs.threaded = false; // stills load everything they show
        auto c = city::CityRendererGL::create(scene, settings.cityTree.string(), cs);
        if (!c) return c.error();
        cityRenderer = std::move(*c);
    }
    for (const StillRequest& s : stills) {
        (*clipmap)->update(clipmapCentres(scene, s.camera, width, height, settings.centers, geometry));
        const ClipmapFrameStats loaded = (*clipmap)->completeSynchronously(); // a still waits for its texels
        // A block that could not be read would be drawn from a coarser level: the still is not written, the
        // damaged pyramid is rebuilt.
        if (const auto& e = (*clipmap)->readError()) return Error{e->message};
        if (canopy) canopy->completeSynchronously();
        if (trunks && s.imagery.view == ImageryView::Canopy) trunks->find();
        (*renderer)->updateGeometry(s.camera, height);
        (*renderer)->completeGeometry();
        if (const auto e = (*renderer)->geometry().elevationReadError()) return Error{e->message};
        const bool stacked = s.imagery.view == ImageryView::Canopy && settings.canopy.layers > 0;
        const CanopyDrawSettings cd = canopyDrawSettings(scene, settings.canopy, s.imagery);
        ImagerySettings imagery = s.imagery;
        // Layers on the ground: the ground draws layer 0; over trunks it shows its own season under the crowns.
        if (stacked && cd.crownBase <= 0.0) imagery.canopyBase = cd.darkest;
        GeometryFrameStats drawn = stacked ? canopyRenderer->renderView(s.camera, **renderer, imagery, *canopy, cd,
                                                                        trunks.get(), target)
                                           : (*renderer)->render(s.camera, imagery, target);
        std::optional<city::CityFrameStats> cityStats;
        if (cityRenderer) {
            std::vector<std::uint8_t> ground;
            if (!s.cityAccuracyOut.empty()) ground = target.readRgba();
            cityRenderer->settings().roofs = city::roofImageryFor(s.imagery);
            cityRenderer->complete(s.camera, width, height);
            cityRenderer->resetOcclusion(); // a still: every node tested before it is drawn
            const city::CityFrameStats cst = cityRenderer->draw(s.camera, renderer->get(), target);
            cityStats = cst;
            drawn.triangles += cst.triangles;
            drawn.drawCalls += cst.drawCalls;
            if (!s.cityAccuracyOut.empty()) {
                // The same view with the original textures, over the terrain as it was: PSNR over the pixels the
                // city drew (those that differ from the terrain alone in either image).
                const std::vector<std::uint8_t> mine = target.readRgba();
                city::CitySettings os = cityRenderer->settings();
                os.mode = city::CityMode::Original;
                os.threaded = false;
                os.capacityBytes = std::max<std::uint64_t>(os.capacityBytes, 4ull << 30);
                auto orig = city::CityRendererGL::create(scene, settings.cityTree.string(), os);
                if (!orig) return orig.error();
                (*renderer)->render(s.camera, imagery, target);
                (*orig)->complete(s.camera, width, height);
                const city::CityFrameStats ost = (*orig)->draw(s.camera, renderer->get(), target);
                const std::vector<std::uint8_t> ref = target.readRgba();
                double sq = 0.0;
                std::int64_t n = 0;
                for (std::size_t i = 0; i < ref.size(); i += 4) {
                    int changed = 0;
                    for (std::size_t c = 0; c < 3; ++c)
                        changed += std::abs(int(mine[i + c]) - int(ground[i + c])) + std::abs(int(ref[i + c]) - int(ground[i + c]));
                    if (changed == 0) continue;
                    ++n;
                    for (std::size_t c = 0; c < 3; ++c) {
                        const double d = double(mine[i + c]) - double(ref[i + c]);
                        sq += d * d;
                    }
                }
                const double mse = n ? sq / double(n * 3) : 0.0;
                nlohmann::json j = {{"camera", s.camera.toString()},
                                    {"size", {width, height}},
                                    {"mode", city::cityModeName(cityRenderer->settings().mode)},
                                    {"against", "original"},
                                    {"psnr_db", mse > 0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : 999.0},
                                    {"city_pixels", n},
                                    {"atlas_nodes", cst.atlasNodes},
                                    {"original_leaves", cst.originalLeaves},
                                    {"coarser_than_wanted", cst.coarserThanWanted},
                                    {"original_missing_textures", ost.missingOriginals}};
                std::string err;
                if (!writeTextAtomic(s.cityAccuracyOut, j.dump(2) + "\n", err))
                    return fileError(s.cityAccuracyOut.string(), err);
                // Back to this mode's picture for the image file.
                (*renderer)->render(s.camera, imagery, target);
                cityRenderer->draw(s.camera, renderer->get(), target);
            }
        }
        if (auto st = checkGl(s.out); !st) return st.error();
        if (auto st = writeRgb(target, s.out); !st) return st.error();
        present();
        if (!s.accuracyOut.empty()) {
            // The same camera through the brute-force renderer: colour PSNR and geometric accuracy.
            const std::vector<std::uint8_t> mine = target.readRgba();
            const std::vector<float> mineDepth = target.readDepth();
            if (!reference) {
                ReferenceOptions ro;
                ro.anisotropy = s.imagery.anisotropy;
                ro.levelZero = levelZeroOf(scene, pyramids);
                auto r = ReferenceRendererGL::create(scene, ro);
                if (!r) return r.error();
                reference = std::move(*r);
            }
            const ImageryView v = s.imagery.view == ImageryView::LeafOff ? ImageryView::LeafOff : ImageryView::LeafOn;
            reference->render(s.camera, v == ImageryView::LeafOn ? Season::LeafOn : Season::LeafOff, target);
            const std::vector<std::uint8_t> ref = target.readRgba();
            const DepthAccuracy acc = compareDepth(target.readDepth(), mineDepth, width, height, kNearPlane);
            double sq = 0;
            for (size_t i = 0; i < ref.size(); i += 4)
                for (size_t c = 0; c < 3; ++c) {
                    const double d = double(ref[i + c]) - double(mine[i + c]);
                    sq += d * d;
                }
            const double mse = sq / double(ref.size() / 4 * 3);
            nlohmann::json j = {{"camera", s.camera.toString()},
                                {"size", {width, height}},
                                {"view", imageryViewName(v)},
                                {"psnr_db", mse > 0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : 999.0},
                                {"mean_depth_error_px", acc.meanErrorPx},
                                {"p95_depth_error_px", acc.p95ErrorPx},
                                {"mean_abs_depth_difference_m", acc.meanAbsDepthM},
                                {"terrain_pixels_compared", acc.pixels},
                                {"pixels_terrain_in_one_only", acc.onlyOne},
                                {"triangles", drawn.triangles},
                                {"reference_triangles", reference->stats().triangles},
                                {"grid_size", settings.geometry.n},
                                {"device", (*ctx)->info().renderer}};
            std::string err;
            if (!writeTextAtomic(s.accuracyOut, j.dump(2) + "\n", err)) return fileError(s.accuracyOut.string(), err);
            if (auto st = checkGl(s.accuracyOut); !st) return st.error();
        }
        if (!s.statsOut.empty()) {
            if (!scratch) scratch = std::make_unique<gl::RenderTarget>(width, height);
            const FrameLevelStats ls = (*renderer)->measureLevels(s.camera, *scratch);
            nlohmann::json j = {{"renderer", "clipmap"},
                                {"centers", placementName(settings.centers)},
                                {"view", imageryViewName(s.imagery.view)},
                                {"camera", s.camera.toString()},
                                {"size", {width, height}},
                                {"clip_size", geometry.size},
                                {"clip_levels", geometry.levels},
                                {"coverage", ls.coverage},
                                {"mean_level_deficit", ls.meanLevelDeficit},
                                {"used_level_histogram", ls.usedLevelHistogram},
                                {"terrain_pixels", ls.terrainPixels},
                                {"texels_uploaded", (*clipmap)->totalTexelsUploaded()},
                                {"blocks_missing", loaded.blocksMissing},
                                {"resident_texture_bytes", (*clipmap)->residentBytes()},
                                {"loader_cache_bytes", (*clipmap)->loaderCacheBytes()},
                                {"triangles", drawn.triangles},
                                {"elevation_resident_bytes", (*renderer)->geometry().residentBytes()},
                                {"device", (*ctx)->info().renderer}};
            if (cityStats)
                j["city"] = {{"mode", city::cityModeName(cityRenderer->settings().mode)},
                             {"occlusion", cityRenderer->settings().occlusion &&
                                               cityRenderer->settings().mode == city::CityMode::Atlas},
                             {"atlas_nodes", cityStats->atlasNodes},
                             {"original_leaves", cityStats->originalLeaves},
                             {"coarser_than_wanted", cityStats->coarserThanWanted},
                             {"occluded_nodes", cityStats->occludedNodes},
                             {"occlusion_queries", cityStats->occlusionQueries},
                             {"occlusion_waits", cityStats->occlusionWaits},
                             {"draw_calls", cityStats->drawCalls},
                             {"texture_binds", cityStats->textureBinds},
                             {"triangles", cityStats->triangles},
                             {"resident_bytes", cityStats->residentBytes},
                             {"allocated_bytes", cityStats->allocatedBytes},
                             {"blocks_resident", cityStats->blocksResident},
                             {"loader_queue", cityStats->loaderQueue}};
            std::string err;
            if (!writeTextAtomic(s.statsOut, j.dump(2) + "\n", err)) return fileError(s.statsOut.string(), err);
            if (auto st = checkGl(s.statsOut); !st) return st.error();
        }
    }
    return (*ctx)->info();
}

} // namespace

Result<gl::ContextInfo> renderStills(const Scene& scene, int width, int height, const std::vector<StillRequest>& stills,
                                     const RenderSettings& settings) {
    auto first = renderStillsOnce(scene, width, height, stills, settings);
    if (first || !rebuildingDamaged(first.message(), settings.cacheDir)) return first;
    return renderStillsOnce(scene, width, height, stills, settings);
}

void printSceneNotes(const Scene& scene) {
    for (const auto& w : scene.sources.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
    for (const auto& n : scene.notes) std::printf("note: %s\n", n.c_str()); // information, not a problem: stdout
    std::fflush(stdout);
}

} // namespace seasonview::app
