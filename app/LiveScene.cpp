#include "LiveScene.h"

#include "RenderJob.h"

#include <algorithm>
#include <cstdio>

namespace seasonview::app {

Status LiveScene::ensureCanopy(const ViewerSettings& s) {
    const int layers = std::max(1, s.layers);
    const bool wantTrunks = s.trunks && s.layers > 0;
    if (canopy && canopyParams.method == s.params.method && canopyParams.k == s.params.k && canopyLayers == layers &&
        canopyTrunks == wantTrunks)
        return Ok{};
    if (!histograms) {
        auto h = preparePairStats(*scene, pyramids, cache);
        if (!h) return h.error();
        histograms = std::move(*h);
    }
    trunks.reset();
    terrain->setCanopy(nullptr);
    canopy.reset();
    CanopyOptions co;
    co.params = s.params;
    co.layers = layers;
    co.onDemand = s.canopyLevelsRead;
    co.derivation = s.canopyDerivation;
    const SegmentationStats stats = statsFromHistograms(*histograms, co.params.method);
    auto p = canopyPyramid(pyramids, co, stats, cache, false); // where `prepare` made it
    if (!p) return p.error();
    co.precomputed = std::move(*p);
    auto c = CanopyClipmapGL::create(*clip, stats, co);
    if (!c) return c.error();
    canopy = std::move(*c);
    terrain->setCanopy(canopy.get());
    if (!canopyRenderer) {
        auto cr = CanopyRendererGL::create();
        if (!cr) return cr.error();
        canopyRenderer = std::move(*cr);
    }
    if (wantTrunks) {
        auto t = TrunksGL::create(*scene, *clip, *canopy);
        if (!t) return t.error();
        trunks = std::move(*t);
        canopy->keepLevelsFrom(trunks->level()); // the crown search reads its level whole
    }
    canopyParams = s.params;
    canopyLayers = layers;
    canopyTrunks = wantTrunks;
    return Ok{};
}

void LiveScene::reportDamage() {
    if (!damagedReported) {
        // Never drawn (coarser levels stand in, of the imagery or the elevation); rebuilt on the next start.
        std::optional<ClipmapGL::ReadError> e = clip->readError();
        if (!e) e = terrain->geometry().elevationReadError();
        if (!e && canopy && !canopy->readError().empty()) e = ClipmapGL::ReadError{canopy->readError(), -1};
        if (e) {
            invalidateDamagedPyramid(e->message, cache);
            damagedReported = true;
            std::fprintf(stderr, "seasonview view: %s (damaged in the cache: drawn from coarser levels, rebuilt from "
                                 "the source on the next start)\n", e->message.c_str());
        }
    }
    // A streamed tile that failed (a service's fault): said once a new error comes, and on the HUD.
    if (clip->streamErrors() > streamErrorsReported) {
        if (streamErrorsReported == 0 || clip->lastStreamError() != lastStreamErrorReported)
            std::fprintf(stderr, "seasonview view: %s (streamed: drawn from coarser levels, asked again in a few "
                                 "seconds)\n", clip->lastStreamError().c_str());
        streamErrorsReported = clip->streamErrors();
        lastStreamErrorReported = clip->lastStreamError();
    }
    if (city && !cityDamageReported)
        if (const std::string e = city->readError(); !e.empty()) {
            cityDamageReported = true;
            std::fprintf(stderr, "seasonview view: %s (not drawn)\n", e.c_str());
        }
}

GeometryFrameStats LiveScene::draw(const Camera& cam, const ViewerSettings& s, const gl::RenderTarget& target,
                                   bool complete) {
    const int w = target.width(), h = target.height();
    const ClipmapGeometry g = clipmapGeometry(*scene, clip->schedule().layout());
    lastLoad = clip->update(clipmapCentres(*scene, cam, w, h, s.centers, g));
    texelsTotal += lastLoad.texelsUploaded;
    terrain->updateGeometry(cam, h);
    if (complete) {
        const ClipmapFrameStats more = clip->completeSynchronously();
        texelsTotal += more.texelsUploaded;
        terrain->completeGeometry();
    }
    const bool canopyView = s.imagery.view == ImageryView::Canopy;
    if (canopyView && canopy) {
        if (complete) {
            canopy->completeSynchronously();
            if (trunks) trunks->find();
        } else {
            canopy->update();
            if (trunks) trunks->update();
        }
    }
    ImagerySettings im = s.imagery;
    CanopyRenderSettings cs;
    cs.params = s.params;
    cs.layers = s.layers;
    cs.trunks = trunks != nullptr;
    cs.draw = s.marchLayers ? CanopyDrawMode::March : CanopyDrawMode::Layers;
    const CanopyDrawSettings cd = canopyDrawSettings(*scene, cs, im);
    const bool stacked = canopyView && canopy && s.layers > 0;
    if (stacked && cd.crownBase <= 0.0) im.canopyBase = cd.darkest;
    GeometryFrameStats drawn = stacked ? canopyRenderer->renderView(cam, *terrain, im, *canopy, cd, trunks.get(), target)
                                       : terrain->render(cam, im, target);
    cityStats = {};
    if (city && s.city) {
        city->settings().tpp = std::max(0.05f, s.cityTpp);
        if (city->hasBlockMaps()) city->settings().mode = s.cityBlockMaps ? city::CityMode::BlockMap : city::CityMode::Atlas;
        city->settings().view = city::cityViewFor(im);
        if (complete) city->complete(cam, target.width(), target.height());
        else city->update(cam, target.width(), target.height());
        cityStats = city->draw(cam, terrain.get(), target);
        drawn.triangles += cityStats.triangles;
        drawn.drawCalls += cityStats.drawCalls;
    }
    reportDamage();
    return drawn;
}

bool applySetting(ViewerSettings& s, const std::string& name, const nlohmann::json& v, std::string& err) {
    auto str = [&]() { return v.is_string() ? v.get<std::string>() : v.dump(); };
    if (name == "view") {
        auto view = parseImageryView(str());
        if (!view) return err = "view '" + str() + "' unknown", false;
        s.imagery.view = *view;
    } else if (name == "blend" && v.is_number()) {
        s.imagery.blend = std::clamp(v.get<float>(), 0.0f, 1.0f);
    } else if (name == "swipe" && v.is_number()) {
        s.imagery.swipe = std::clamp(v.get<float>(), 0.0f, 1.0f);
    } else if (name == "shading" && v.is_number()) {
        s.imagery.shading = std::clamp(v.get<float>(), 0.0f, 1.0f);
    } else if (name == "layers") {
        if (v.is_string() && v.get<std::string>() == "off") s.layers = 0;
        else if (v.is_number_integer() && v.get<int>() >= 1 && v.get<int>() <= 64) s.layers = v.get<int>();
        else return err = "layers must be 1..64 or \"off\"", false;
    } else if (name == "city" && v.is_boolean()) {
        s.city = v.get<bool>();
    } else if (name == "city_blockmaps" && v.is_boolean()) {
        s.cityBlockMaps = v.get<bool>();
    } else if (name == "city_tpp" && v.is_number()) {
        s.cityTpp = std::clamp(v.get<float>(), 0.05f, 16.0f);
    } else if (name == "trunks" && v.is_boolean()) {
        s.trunks = v.get<bool>();
    } else if (name == "canopy_draw" && (str() == "layers" || str() == "march")) {
        s.marchLayers = str() == "march";
    } else if (name == "centers") {
        auto c = parsePlacement(str());
        if (!c) return err = "centers '" + str() + "' unknown", false;
        s.centers = *c;
    } else if (name == "method") {
        auto m = parseSegmentationMethod(str());
        if (!m) return err = "method '" + str() + "' unknown", false;
        s.params.method = *m;
    } else if (name == "k" && v.is_number_integer() && v.get<int>() >= 1 && v.get<int>() <= kSegMaxK &&
               v.get<int>() % 2 == 1) {
        s.params.k = v.get<int>();
    } else if (name == "panel" && v.is_boolean()) {
        s.panel = v.get<bool>();
    } else {
        err = "setting '" + name + "' with value " + v.dump() + " not understood";
        return false;
    }
    return true;
}

} // namespace seasonview::app
