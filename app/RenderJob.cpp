#include "RenderJob.h"

#include "StreamedPyramid.h"

#include "CityJob.h"

#include "CanopyClipmapGL.h"
#include "CanopyPyramid.h"
#include "CanopyRendererGL.h"
#include "TrunksGL.h"

#include "DepthAccuracy.h"
#include "ElevationPyramid.h"

#include "AtomicFile.h"
#include "Commands.h"
#include "WebSource.h"
#include "gl/GlDebug.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace seasonview::app {

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
    if (invalidateDamagedPyramid(message, cacheDir)) {
        std::printf("note: %s: damaged in the cache; its pyramid is rebuilt from the source\n", message.c_str());
        std::fflush(stdout);
        return true;
    }
    // A city's atlas tree is built before the stills or frames that read it: removed here, built on the next run.
    if (removeDamagedCityTree(message, cacheDir)) {
        std::printf("note: %s: damaged in the cache; removed, built again from the city model on the next run\n",
                    message.c_str());
        std::fflush(stdout);
    }
    return false;
}

struct LayerPrepareProgress::State {
    ProgressFn bar;
    bool service = false;
    std::optional<long long> total;
    std::optional<web::TileFetchCounter> counter;
    std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now(), lastScan{};
    web::TileFetchCounter::Count count;
};

LayerPrepareProgress::LayerPrepareProgress(const char* name, const ImageryLayer& layer,
                                           const std::filesystem::path& cacheDir)
    : m(std::make_shared<State>()) {
    m->bar = terminalProgress(name);
    if (layer.source.tiles.size() == 1) {
        const std::filesystem::path& p = layer.source.tiles.front().path;
        m->total = web::serviceTileCount(p);
        m->service = m->total || web::serviceIdentity(p);
    }
    if (m->service) m->counter.emplace(cacheDir / "web" / "tiles");
}

ProgressFn LayerPrepareProgress::fn() const {
    if (!m->bar || !m->service) return m->bar;
    return [s = m](double f, const char* stage) {
        // The tile cache scanned at most once a second: the tiles fetched so far, and the time left at this rate.
        const auto now = std::chrono::steady_clock::now();
        if (now - s->lastScan > std::chrono::seconds(1) || f >= 1.0) {
            s->count = s->counter->fetched();
            s->lastScan = now;
        }
        const double elapsed = std::chrono::duration<double>(now - s->start).count();
        char text[160];
        std::snprintf(text, sizeof text, "%lld%s%s tiles, %.1f MB, ETA %s", s->count.tiles, s->total ? " of " : "",
                      s->total ? std::to_string(*s->total).c_str() : "", double(s->count.bytes) / 1e6,
                      f > 0.01 && f < 1.0 ? (std::to_string(int(elapsed * (1.0 - f) / f + 0.5)) + " s").c_str() : "-");
        (void)stage;
        std::string line = text;
        line.resize(std::max<size_t>(line.size(), 48), ' '); // a fixed width: a shorter line covers a longer one
        s->bar(f, line.c_str());
    };
}

std::string LayerPrepareProgress::note() const {
    if (!m->service) return {};
    m->count = m->counter->fetched();
    char text[160];
    std::snprintf(text, sizeof text, "fetched %lld%s%s tiles (%.2f MB) from the service", m->count.tiles,
                  m->total ? " of " : "", m->total ? std::to_string(*m->total).c_str() : "",
                  double(m->count.bytes) / 1e6);
    return text;
}

namespace {

Result<std::vector<ImagePyramid>> preparePyramidsOnce(const Scene& scene, const std::filesystem::path& cacheDir,
                                                      std::vector<ImagePyramid>& out) {
    out.clear();
    const std::pair<const char*, const ImageryLayer*> layers[] = {{"leafon", &scene.leafon}, {"leafoff", &scene.leafoff}};
    for (const auto& [name, layer] : layers) {
        PrepareOptions o;
        o.cacheDir = cacheDir;
        const LayerPrepareProgress progress(name, *layer, cacheDir);
        o.progress = progress.fn();
        auto report = prepareSeasonPyramid(scene, name, o);
        if (!report) return report.error();
        if (report->built) {
            const std::string fetched = progress.note();
            std::printf("prepared %s pyramid in %.2f s (%s)%s%s\n", name, report->seconds, report->reason.c_str(),
                        fetched.empty() ? "" : ": ", fetched.c_str());
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
    assert(pyramids.size() == 2 && pyramids[0].streamedLevels == 0 && pyramids[1].streamedLevels == 0 &&
           "levelZeroOf(): the scene's two prepared pyramids (streamed scenes are refused by refuseStreamed)");
    return std::array<std::filesystem::path, 2>{pyramids[0].levels[0].file, pyramids[1].levels[0].file};
}

Result<SegmentationHistograms> preparePairStats(const Scene& scene, const std::vector<ImagePyramid>& pyramids,
                                                const std::filesystem::path& cacheDir) {
    assert(pyramids.size() == 2 && pyramids[0].width() == scene.leafon.info.width &&
           pyramids[0].height() == scene.leafon.info.height &&
           "preparePairStats(): the leaf-on and leaf-off pyramids of the scene");
    (void)scene; // only checked: the pyramids' source keys already name both layers and their stretches
    PairHistogramsReport report;
    // Streamed seasons: the statistics of the first level both have on disk (their colours' distribution, a little
    // narrowed by the box filter), not of texels never fetched.
    const std::vector<ImagePyramid> prepared = preparedPart(pyramids);
    auto histograms = preparePairHistograms(prepared[0], prepared[1], cacheDir, terminalProgress("pair stats"), &report);
    if (!histograms) return histograms.error();
    if (report.built) {
        std::printf("prepared pair statistics in %.2f s (%s)\n", report.seconds, report.reason.c_str());
        std::fflush(stdout);
    }
    return histograms;
}

PyramidSource canopyLayerSource(const std::vector<ImagePyramid>& pyramids, const CanopyOptions& options,
                                const SegmentationStats& stats) {
    assert(pyramids.size() == 2 && "canopyLayerSource(): the leaf-on and leaf-off pyramids");
    const CanopyPyramidParams params{options.params, options.layers, canopyTopK(options.params, options.topK)};
    return canopyPyramidSource(pyramids[0], pyramids[1], params, stats);
}

std::string canopyLayerName(const CanopyOptions& options) {
    return std::string(kSegmentationMethodNames[size_t(options.params.method)]) + ", k " +
           std::to_string(effectiveK(options.params)) + ", " + std::to_string(options.layers) + " layers";
}

Result<std::optional<ImagePyramid>> canopyPyramid(const std::vector<ImagePyramid>& pyramids,
                                                  const CanopyOptions& options, const SegmentationStats& stats,
                                                  const std::filesystem::path& cacheDir, bool build) {
    assert(pyramids.size() == 2 && "canopyPyramid(): the leaf-on and leaf-off pyramids");
    if (pyramids[0].streamedLevels > 0 || pyramids[1].streamedLevels > 0) return std::optional<ImagePyramid>();
    const PyramidSource source = canopyLayerSource(pyramids, options, stats);
    if (!build) {
        // Not prepared, or damaged (the next prepare rebuilds it): the loader derives the blocks as before.
        auto p = openPyramid(source, cacheDir);
        return p ? std::optional<ImagePyramid>(std::move(*p)) : std::optional<ImagePyramid>();
    }
    PrepareOptions o;
    o.cacheDir = cacheDir;
    o.progress = terminalProgress("canopy");
    auto report = preparePyramid(source, o);
    if (!report) return report.error();
    if (report->built) {
        std::printf("prepared the canopy layer (%s) in %.2f s (%s)\n", canopyLayerName(options).c_str(),
                    report->seconds, report->reason.c_str());
        std::fflush(stdout);
    }
    return std::optional<ImagePyramid>(std::move(report->pyramid));
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

void printSceneNotes(const Scene& scene) {
    for (const auto& w : scene.sources.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
    for (const auto& n : scene.notes) std::printf("note: %s\n", n.c_str()); // information, not a problem: stdout
    std::fflush(stdout);
}

} // namespace seasonview::app
