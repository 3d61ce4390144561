// renderStills (RenderJob.h): stills through the reference renderer, or through the clipmaps with the canopy view and
// the city, each written atomically with its optional accuracy and statistics files.
#include "CityJob.h"
#include "RenderJob.h"
#include "StreamedPyramid.h"

#include "CanopyClipmapGL.h"
#include "CanopyRendererGL.h"
#include "DepthAccuracy.h"
#include "TrunksGL.h"

#include "AtomicFile.h"
#include "gl/GlDebug.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <memory>

namespace seasonview::app {

namespace {

// PSNR in dB of a squared error sum over `values` channel values (999 for identical images).
double psnr(double squaredErrors, double values) {
    const double mse = values > 0 ? squaredErrors / values : 0.0;
    return mse > 0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : 999.0;
}

// RGBA of `w` × `h` pixels box-filtered by `k` × `k` (the mean of each block, rounded).
std::vector<std::uint8_t> boxFiltered(const std::vector<std::uint8_t>& rgba, int w, int h, int k) {
    if (k <= 1) return rgba;
    const int ow = w / k, oh = h / k;
    std::vector<std::uint8_t> out(std::size_t(ow) * std::size_t(oh) * 4);
    const int n = k * k;
    for (int y = 0; y < oh; ++y)
        for (int x = 0; x < ow; ++x)
            for (int c = 0; c < 4; ++c) {
                int sum = 0;
                for (int j = 0; j < k; ++j)
                    for (int i = 0; i < k; ++i)
                        sum += rgba[(std::size_t(y * k + j) * std::size_t(w) + std::size_t(x * k + i)) * 4 +
                                    std::size_t(c)];
                out[(std::size_t(y) * std::size_t(ow) + std::size_t(x)) * 4 + std::size_t(c)] =
                    std::uint8_t((sum + n / 2) / n);
            }
    return out;
}

// One context's stills: what every still needs (the context, the target, GL error checks, a window to show them in).
// With RenderSettings::supersample K the target holds K × K samples a pixel: width and height are the samples', and
// readRgba() and write() give the output's pixels.
struct StillContext {
    std::unique_ptr<gl::GlContext> ctx;
    const RenderSettings& settings;
    int samples;             // K
    int outWidth, outHeight; // the output's pixels
    int width, height;       // the target's: the samples
    int errorsBefore;
    gl::RenderTarget target;

    StillContext(std::unique_ptr<gl::GlContext> c, const RenderSettings& s, int w, int h)
        : ctx(std::move(c)), settings(s), samples(std::max(1, s.supersample)), outWidth(w), outHeight(h),
          width(w * samples), height(h * samples), errorsBefore(gl::debugErrorCount()), target(width, height) {}

    /// The picture at the output's size (each pixel the mean of its samples), rows from the top.
    std::vector<std::uint8_t> readRgba() const { return boxFiltered(target.readRgba(), width, height, samples); }

    Status checkGl(const std::filesystem::path& out) const {
        if (const std::string e = gl::drainErrors(); !e.empty() || gl::debugErrorCount() != errorsBefore)
            return Error{"OpenGL error while rendering " + out.string() + (e.empty() ? "" : ": " + e)};
        return Ok{};
    }
    // With --window, the still is shown too.
    void present() {
        if (!settings.windowed) return;
        int fw = 0, fh = 0;
        ctx->framebufferSize(fw, fh);
        target.blitToDefault(fw, fh);
        ctx->swapBuffers();
    }
    Status write(const std::filesystem::path& out) {
        if (auto st = checkGl(out); !st) return st;
        if (samples == 1) {
            if (auto st = writeRgb(target, out); !st) return st;
        } else {
            const std::vector<std::uint8_t> rgba = readRgba();
            std::vector<std::uint8_t> rgb(rgba.size() / 4 * 3);
            for (std::size_t i = 0; i < rgba.size() / 4; ++i)
                for (std::size_t c = 0; c < 3; ++c) rgb[i * 3 + c] = rgba[i * 4 + c];
            if (auto st = writeImageAtomic(out, rgb.data(), outWidth, outHeight, 3); !st) return st;
        }
        present();
        return Ok{};
    }
};

Status renderReferenceStills(const Scene& scene, const std::vector<ImagePyramid>& pyramids,
                             const std::vector<StillRequest>& stills, StillContext& c) {
    ReferenceOptions options;
    options.anisotropy = c.settings.referenceAnisotropy;
    if (auto st = refuseStreamed(pyramids, "the reference renderer"); !st) return st;
    options.levelZero = levelZeroOf(scene, pyramids);
    auto renderer = ReferenceRendererGL::create(scene, options);
    if (!renderer) return renderer.error();
    for (const StillRequest& s : stills) {
        const ImageryView v = s.imagery.view;
        if (v != ImageryView::LeafOn && v != ImageryView::LeafOff)
            return Error{std::string("--view ") + imageryViewName(v) + " needs --renderer clipmap"};
        (*renderer)->render(s.camera, v == ImageryView::LeafOn ? Season::LeafOn : Season::LeafOff, c.target);
        if (auto st = c.write(s.out); !st) return st;
    }
    return Ok{};
}

// The clipmap renderer's stills: the terrain, the canopy view's layers when a still asks for them, the city.
class ClipmapStills {
public:
    ClipmapStills(const Scene& scene, const std::vector<ImagePyramid>& pyramids, StillContext& c)
        : m_scene(scene), m_pyramids(pyramids), m_c(c), m_settings(c.settings) {}

    Status create(const std::vector<StillRequest>& stills);
    Status render(const StillRequest& s);

private:
    Status createCanopy();
    GeometryFrameStats drawTerrain(const StillRequest& s, ImagerySettings& imagery);
    Result<city::CityFrameStats> drawCity(const StillRequest& s, const ImagerySettings& imagery);
    Status writeCityAccuracy(const StillRequest& s, const ImagerySettings& imagery, const std::vector<std::uint8_t>& ground,
                             const city::CityFrameStats& cst);
    Status writeAccuracy(const StillRequest& s, const GeometryFrameStats& drawn);
    Status writeStats(const StillRequest& s, const ClipmapFrameStats& loaded, const GeometryFrameStats& drawn,
                      const std::optional<city::CityFrameStats>& cityStats);

    const Scene& m_scene;
    const std::vector<ImagePyramid>& m_pyramids;
    StillContext& m_c;
    const RenderSettings& m_settings;
    std::unique_ptr<ClipmapGL> m_clipmap;
    std::unique_ptr<ClipmapTerrainRendererGL> m_renderer;
    ClipmapGeometry m_geometry;
    std::unique_ptr<CanopyClipmapGL> m_canopy;
    std::unique_ptr<CanopyRendererGL> m_canopyRenderer;
    std::unique_ptr<TrunksGL> m_trunks;
    std::unique_ptr<gl::RenderTarget> m_scratch;
    std::unique_ptr<ReferenceRendererGL> m_reference;
    std::unique_ptr<city::CityRendererGL> m_city;
};

Status ClipmapStills::create(const std::vector<StillRequest>& stills) {
    auto clipmap = ClipmapGL::create(m_pyramids, m_settings.clipmap);
    if (!clipmap) return clipmap.error();
    m_clipmap = std::move(*clipmap);
    auto elevation = prepareElevation(m_scene, m_settings.cacheDir);
    if (!elevation) return elevation.error();
    auto renderer = ClipmapTerrainRendererGL::create(m_scene, *m_clipmap, *elevation ? &**elevation : nullptr,
                                                     m_settings.geometry);
    if (!renderer) return renderer.error();
    m_renderer = std::move(*renderer);
    m_geometry = clipmapGeometry(m_scene, m_clipmap->schedule().layout());
    // The canopy view's derived layer and stacked layers, made when a still asks for them.
    if (std::any_of(stills.begin(), stills.end(), [](const StillRequest& s) { return s.imagery.view == ImageryView::Canopy; }))
        if (auto st = createCanopy(); !st) return st;
    if (m_settings.city) {
        city::CitySettings cs = *m_settings.city;
        cs.threaded = false; // stills load everything they show
        cs.tpp *= double(m_c.samples); // the levels of detail of the output's pixels
        cs.blockMapErrorPx *= double(m_c.samples);
        if (auto st = prepareCityBlockMaps(m_scene, m_settings.cityTree, m_settings.cacheDir, cs); !st) return st.error();
        auto c = city::CityRendererGL::create(m_scene, m_settings.cityTree.string(), cs);
        if (!c) return c.error();
        m_city = std::move(*c);
    }
    return Ok{};
}

Status ClipmapStills::createCanopy() {
    auto hist = preparePairStats(m_scene, m_pyramids, m_settings.cacheDir);
    if (!hist) return hist.error();
    CanopyOptions co;
    co.params = m_settings.canopy.params;
    co.layers = std::max(1, m_settings.canopy.layers);
    co.derivation = m_settings.canopy.derivation;
    const SegmentationStats stats = statsFromHistograms(*hist, co.params.method);
    auto p = canopyPyramid(m_pyramids, co, stats, m_settings.cacheDir, false); // where `prepare` made it
    if (!p) return p.error();
    co.precomputed = std::move(*p);
    auto c = CanopyClipmapGL::create(*m_clipmap, stats, co);
    if (!c) return c.error();
    m_canopy = std::move(*c);
    auto cr = CanopyRendererGL::create();
    if (!cr) return cr.error();
    m_canopyRenderer = std::move(*cr);
    m_renderer->setCanopy(m_canopy.get());
    if (m_settings.canopy.trunks && m_settings.canopy.layers > 0) {
        auto t = TrunksGL::create(m_scene, *m_clipmap, *m_canopy);
        if (!t) return t.error();
        m_trunks = std::move(*t);
    }
    return Ok{};
}

Status ClipmapStills::render(const StillRequest& s) {
    m_clipmap->update(clipmapCentres(m_scene, s.camera, m_c.width, m_c.height, m_settings.centers, m_geometry));
    const ClipmapFrameStats loaded = m_clipmap->completeSynchronously(); // a still waits for its texels
    // A block that could not be read would be drawn from a coarser level: the still is not written, the damaged
    // pyramid is rebuilt.
    if (const auto& e = m_clipmap->readError()) return Error{e->message};
    if (m_clipmap->streamErrors() > 0) return Error{m_clipmap->lastStreamError()}; // a streamed tile failed
    if (m_canopy) {
        m_canopy->completeSynchronously();
        if (!m_canopy->readError().empty()) return Error{m_canopy->readError()}; // a block would be drawn coarser
    }
    if (m_trunks && s.imagery.view == ImageryView::Canopy) m_trunks->find();
    m_renderer->updateGeometry(s.camera, m_c.height);
    m_renderer->completeGeometry();
    if (const auto e = m_renderer->geometry().elevationReadError()) return Error{e->message};
    ImagerySettings imagery = s.imagery;
    GeometryFrameStats drawn = drawTerrain(s, imagery);
    std::optional<city::CityFrameStats> cityStats;
    if (m_city) {
        auto cst = drawCity(s, imagery);
        if (!cst) return cst.error();
        cityStats = *cst;
        drawn.triangles += cst->triangles;
        drawn.drawCalls += cst->drawCalls;
    }
    if (auto st = m_c.write(s.out); !st) return st;
    if (!s.accuracyOut.empty())
        if (auto st = writeAccuracy(s, drawn); !st) return st;
    if (!s.statsOut.empty())
        if (auto st = writeStats(s, loaded, drawn, cityStats); !st) return st;
    return Ok{};
}

// The terrain, or the canopy view over it; `imagery` as drawn (the canopy's base set).
GeometryFrameStats ClipmapStills::drawTerrain(const StillRequest& s, ImagerySettings& imagery) {
    const bool stacked = s.imagery.view == ImageryView::Canopy && m_settings.canopy.layers > 0;
    const CanopyDrawSettings cd = canopyDrawSettings(m_scene, m_settings.canopy, s.imagery);
    // Layers on the ground: the ground draws layer 0; over trunks it shows its own season under the crowns.
    if (stacked && cd.crownBase <= 0.0) imagery.canopyBase = cd.darkest;
    return stacked ? m_canopyRenderer->renderView(s.camera, *m_renderer, imagery, *m_canopy, cd, m_trunks.get(), m_c.target)
                   : m_renderer->render(s.camera, imagery, m_c.target);
}

// The city over the terrain drawn, every node it needs resident; with --city-accuracy its PSNR file too.
Result<city::CityFrameStats> ClipmapStills::drawCity(const StillRequest& s, const ImagerySettings& imagery) {
    std::vector<std::uint8_t> ground;
    if (!s.cityAccuracyOut.empty()) ground = m_c.readRgba();
    m_city->settings().view = city::cityViewFor(s.imagery);
    m_city->complete(s.camera, m_c.width, m_c.height);
    m_city->resetOcclusion(); // a still: every node tested before it is drawn
    const city::CityFrameStats cst = m_city->draw(s.camera, m_renderer.get(), m_c.target);
    if (std::string e = m_city->readError(); !e.empty()) return Error{e}; // never a still with a block missing
    if (!s.cityAccuracyOut.empty())
        if (auto st = writeCityAccuracy(s, imagery, ground, cst); !st) return st.error();
    return cst;
}

// The same view with the original textures (or in the mode StillRequest::cityAccuracyAgainst names), over the
// terrain as it was: PSNR over the pixels the city drew (those that differ from the terrain alone in either image), at
// the output's pixels. Leaves this mode's picture in the target.
Status ClipmapStills::writeCityAccuracy(const StillRequest& s, const ImagerySettings& imagery,
                                        const std::vector<std::uint8_t>& ground, const city::CityFrameStats& cst) {
    const std::vector<std::uint8_t> mine = m_c.readRgba();
    city::CitySettings os = m_city->settings();
    os.mode = s.cityAccuracyAgainst;
    os.threaded = false;
    os.capacityBytes = std::max<std::uint64_t>(os.capacityBytes, 4ull << 30);
    auto orig = city::CityRendererGL::create(m_scene, m_settings.cityTree.string(), os);
    if (!orig) return orig.error();
    m_renderer->render(s.camera, imagery, m_c.target);
    (*orig)->complete(s.camera, m_c.width, m_c.height);
    const city::CityFrameStats ost = (*orig)->draw(s.camera, m_renderer.get(), m_c.target);
    const std::vector<std::uint8_t> ref = m_c.readRgba();
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
    nlohmann::json j = {{"camera", s.camera.toString()},
                        {"size", {m_c.outWidth, m_c.outHeight}},
                        {"supersample", m_c.samples},
                        {"mode", city::cityModeName(m_city->settings().mode)},
                        {"against", city::cityModeName(s.cityAccuracyAgainst)},
                        {"psnr_db", psnr(sq, double(n * 3))},
                        {"city_pixels", n},
                        {"atlas_nodes", cst.atlasNodes},
                        {"original_leaves", cst.originalLeaves},
                        {"coarser_than_wanted", cst.coarserThanWanted},
                        {"original_missing_textures", ost.missingOriginals},
                        {"block_maps", cst.blockMaps}};
    if (s.cityAccuracyAgainst != city::CityMode::Original) j.erase("original_missing_textures");
    std::string err;
    if (!writeTextAtomic(s.cityAccuracyOut, j.dump(2) + "\n", err)) return fileError(s.cityAccuracyOut.string(), err);
    // Back to this mode's picture for the image file.
    m_renderer->render(s.camera, imagery, m_c.target);
    m_city->draw(s.camera, m_renderer.get(), m_c.target);
    return Ok{};
}

// The same camera through the brute-force renderer: colour PSNR and geometric accuracy.
Status ClipmapStills::writeAccuracy(const StillRequest& s, const GeometryFrameStats& drawn) {
    const std::vector<std::uint8_t> mine = m_c.readRgba();
    const std::vector<float> mineDepth = m_c.target.readDepth();
    if (!m_reference) {
        ReferenceOptions ro;
        ro.anisotropy = s.imagery.anisotropy;
        if (auto st = refuseStreamed(m_pyramids, "the accuracy check (--accuracy)"); !st) return st;
        ro.levelZero = levelZeroOf(m_scene, m_pyramids);
        auto r = ReferenceRendererGL::create(m_scene, ro);
        if (!r) return r.error();
        m_reference = std::move(*r);
    }
    const ImageryView v = s.imagery.view == ImageryView::LeafOff ? ImageryView::LeafOff : ImageryView::LeafOn;
    m_reference->render(s.camera, v == ImageryView::LeafOn ? Season::LeafOn : Season::LeafOff, m_c.target);
    const std::vector<std::uint8_t> ref = m_c.readRgba(); // the output's pixels; depths at the samples
    const DepthAccuracy acc = compareDepth(m_c.target.readDepth(), mineDepth, m_c.width, m_c.height, kNearPlane);
    double sq = 0;
    for (size_t i = 0; i < ref.size(); i += 4)
        for (size_t c = 0; c < 3; ++c) {
            const double d = double(ref[i + c]) - double(mine[i + c]);
            sq += d * d;
        }
    nlohmann::json j = {{"camera", s.camera.toString()},
                        {"size", {m_c.outWidth, m_c.outHeight}},
                        {"supersample", m_c.samples},
                        {"view", imageryViewName(v)},
                        {"psnr_db", psnr(sq, double(ref.size() / 4 * 3))},
                        {"mean_depth_error_px", acc.meanErrorPx},
                        {"p95_depth_error_px", acc.p95ErrorPx},
                        {"mean_abs_depth_difference_m", acc.meanAbsDepthM},
                        {"terrain_pixels_compared", acc.pixels},
                        {"pixels_terrain_in_one_only", acc.onlyOne},
                        {"triangles", drawn.triangles},
                        {"reference_triangles", m_reference->stats().triangles},
                        {"grid_size", m_settings.geometry.n},
                        {"device", m_c.ctx->info().renderer}};
    std::string err;
    if (!writeTextAtomic(s.accuracyOut, j.dump(2) + "\n", err)) return fileError(s.accuracyOut.string(), err);
    return m_c.checkGl(s.accuracyOut);
}

// --stats: the clipmap's levels, uploads and memory for the still, and the city's paging.
Status ClipmapStills::writeStats(const StillRequest& s, const ClipmapFrameStats& loaded, const GeometryFrameStats& drawn,
                                 const std::optional<city::CityFrameStats>& cityStats) {
    if (!m_scratch) m_scratch = std::make_unique<gl::RenderTarget>(m_c.width, m_c.height);
    const FrameLevelStats ls = m_renderer->measureLevels(s.camera, *m_scratch);
    nlohmann::json j = {{"renderer", "clipmap"},
                        {"centers", placementName(m_settings.centers)},
                        {"view", imageryViewName(s.imagery.view)},
                        {"camera", s.camera.toString()},
                        {"size", {m_c.outWidth, m_c.outHeight}},
                        {"supersample", m_c.samples},
                        {"clip_size", m_geometry.size},
                        {"clip_levels", m_geometry.levels},
                        {"coverage", ls.coverage},
                        {"mean_level_deficit", ls.meanLevelDeficit},
                        {"used_level_histogram", ls.usedLevelHistogram},
                        {"terrain_pixels", ls.terrainPixels},
                        {"texels_uploaded", m_clipmap->totalTexelsUploaded()},
                        {"blocks_missing", loaded.blocksMissing},
                        {"resident_texture_bytes", m_clipmap->residentBytes()},
                        {"loader_cache_bytes", m_clipmap->loaderCacheBytes()},
                        {"triangles", drawn.triangles},
                        {"elevation_resident_bytes", m_renderer->geometry().residentBytes()},
                        {"device", m_c.ctx->info().renderer}};
    if (cityStats)
        j["city"] = {{"mode", city::cityModeName(m_city->settings().mode)},
                     {"occlusion", m_city->settings().occlusion && (m_city->settings().mode == city::CityMode::Atlas ||
                                                                    m_city->settings().mode == city::CityMode::BlockMap)},
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
                     {"loader_queue", cityStats->loaderQueue},
                     {"block_maps", cityStats->blockMaps},
                     {"block_maps_not_resident", cityStats->blockMapsNotResident}};
    std::string err;
    if (!writeTextAtomic(s.statsOut, j.dump(2) + "\n", err)) return fileError(s.statsOut.string(), err);
    return m_c.checkGl(s.statsOut);
}

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
    const int k = std::max(1, settings.supersample);
    const char* what = k > 1 ? "--size times --supersample" : "--size";
    if (auto st = gl::checkFramebufferSize((*ctx)->info(), width * k, height * k, what); !st) return st.error();
    StillContext c(std::move(*ctx), settings, width, height);
    if (settings.renderer == RendererKind::Reference) {
        if (auto st = renderReferenceStills(scene, pyramids, stills, c); !st) return st.error();
        return c.ctx->info();
    }
    {
        // The renderers die before the context.
        ClipmapStills clip(scene, pyramids, c);
        if (auto st = clip.create(stills); !st) return st.error();
        for (const StillRequest& s : stills)
            if (auto st = clip.render(s); !st) return st.error();
    }
    return c.ctx->info();
}

} // namespace

Result<gl::ContextInfo> renderStills(const Scene& scene, int width, int height, const std::vector<StillRequest>& stills,
                                     const RenderSettings& settings) {
    auto first = renderStillsOnce(scene, width, height, stills, settings);
    if (first || !rebuildingDamaged(first.message(), settings.cacheDir)) return first;
    return renderStillsOnce(scene, width, height, stills, settings);
}

} // namespace seasonview::app
