// `seasonview render`: one still of a scene.
#include "Commands.h"
#include "CityJob.h"
#include "RenderJob.h"

#include <chrono>
#include <cstdio>
#include <memory>

namespace seasonview::app {

namespace {

struct RenderArgs {
    SceneArgs scene;
    FrameArgs frame;
    ImageryArgs imagery;
    ClipmapArgs clipmap;
    CanopyArgs canopy;
    CityArgs city;
    std::string out, stats, accuracy, cityAccuracy, cityAccuracyAgainst = "original";
    int supersample = 1;
};

// The render and imagery settings of the options, group by group: the first problem as one line naming its option.
Status renderSettingsFrom(const RenderArgs& a, RenderSettings& settings, ImagerySettings& imagery) {
    if (auto st = a.imagery.apply(imagery); !st) return st;
    if (auto st = a.canopy.applyGround(imagery); !st) return st;
    if (auto st = a.clipmap.check(); !st) return st;
    settings.geometry.n = a.clipmap.gridSize;
    settings.referenceAnisotropy = a.imagery.aniso;
    const auto reference = a.clipmap.referenceRenderer();
    if (!reference) return reference.error();
    settings.renderer = *reference ? RendererKind::Reference : RendererKind::Clipmap;
    const auto centers = a.clipmap.placement();
    if (!centers) return centers.error();
    settings.centers = *centers;
    settings.clipmap.size = a.clipmap.clipSize;
    settings.clipmap.minClipLevels = a.clipmap.clipLevels;
    settings.windowed = a.frame.window;
    settings.supersample = a.supersample;
    auto canopy = a.canopy.settings();
    if (!canopy) return canopy.error();
    settings.canopy = *canopy;
    settings.cacheDir = a.scene.cacheDir();
    const ImageryView view = imagery.view;
    if (settings.renderer == RendererKind::Reference && view != ImageryView::LeafOn && view != ImageryView::LeafOff)
        return Error{"--view " + a.imagery.view + " needs --renderer clipmap"};
    if (!a.stats.empty() && settings.renderer == RendererKind::Reference)
        return Error{"--stats needs --renderer clipmap"};
    if (!a.accuracy.empty() && settings.renderer == RendererKind::Reference)
        return Error{"--accuracy needs --renderer clipmap"};
    auto citySettings = a.city.settings();
    if (!citySettings) return Error{citySettings.message()};
    settings.city = *citySettings;
    if (settings.city) settings.city->anisotropy = a.imagery.aniso;
    if (settings.city && settings.renderer == RendererKind::Reference) return Error{"--city needs --renderer clipmap"};
    if (!imagery.terrain) {
        if (!settings.city) return Error{"--terrain off draws only the city: give --city atlas|original|flat"};
        if (view == ImageryView::Canopy) return Error{"--terrain off: the canopy is drawn with the terrain, not without"};
        if (!a.accuracy.empty()) return Error{"--terrain off: --accuracy compares the terrain, which is not drawn"};
    }
    return Ok{};
}

} // namespace

Runner addRenderCommand(CLI::App& app) {
    auto args = std::make_shared<RenderArgs>();
    CLI::App* cmd = app.add_subcommand("render", "Render one still of a scene to PNG/TIFF (headless by default)");
    args->scene.addTo(*cmd);
    args->frame.addTo(*cmd, "Image", {});
    cmd->add_option("--out", args->out, "Output image (.png or .tif)")->required()->group(kFrameGroup);
    cmd->add_option("--stats", args->stats, "Write level statistics (coverage, uploads, memory) to this JSON file")
        ->group(kFrameGroup);
    cmd->add_option("--accuracy", args->accuracy,
                    "Also render the reference and write PSNR and geometric accuracy (mean depth difference in "
                    "screen pixels) to this JSON file")
        ->group(kFrameGroup);
    cmd->add_option("--supersample", args->supersample,
                    "K x K samples a pixel, box-filtered down (antialiasing; the PSNR files compare the filtered "
                    "pixels). The city's atlases and BlockMaps are those the output's pixels need (--city-tpp and "
                    "--city-blockmap-error stay in output pixels)")
        ->check(CLI::Range(1, 8))
        ->capture_default_str()
        ->group(kFrameGroup);
    args->imagery.addTo(*cmd);
    args->clipmap.addTo(*cmd);
    args->canopy.addTo(*cmd);
    args->city.addTo(*cmd);
    cmd->add_option("--city-accuracy", args->cityAccuracy,
                    "With --city: write the city's PSNR against its original textures (same view) to this JSON, or "
                    "against another mode's picture (--city-accuracy-against)")
        ->group(kCityGroup);
    cmd->add_option("--city-accuracy-against", args->cityAccuracyAgainst,
                    "What --city-accuracy compares the city with: original (its own textures) or atlas (the atlas "
                    "mode's picture: e.g. --city blockmap's far field against the polygons it stands for)")
        ->check(CLI::IsMember({"original", "atlas"}))
        ->capture_default_str()
        ->group(kCityGroup);
    return [args]() -> int {
        const auto t0 = std::chrono::steady_clock::now();
        auto fail = [](const std::string& m) {
            std::fprintf(stderr, "seasonview render: %s\n", m.c_str());
            return 1;
        };
        RenderSettings settings;
        ImagerySettings imagery;
        if (auto st = renderSettingsFrom(*args, settings, imagery); !st) return fail(st.message());
        auto size = args->frame.frameSize();
        if (!size) return fail(size.message());
        if (auto st = checkImageOutput(args->out); !st) return fail(st.message());
        auto spec = args->frame.cameraSpec();
        if (!spec) return fail(spec.message());
        auto scene = args->scene.load();
        if (!scene) return fail(scene.message());
        printSceneNotes(*scene);
        if (settings.city) {
            auto tree = prepareCityTree(*scene, settings.cacheDir, args->city.tree);
            if (!tree) return fail(tree.message());
            settings.cityTree = *tree;
        }
        const auto [w, h] = *size;
        const Camera camera = *spec ? (*spec)->resolve([&](double x, double y) { return scene->terrainHeight(x, y); })
                                   : overviewCamera(*scene, double(w) / double(h));
        if (!args->cityAccuracy.empty() && !settings.city) return fail("--city-accuracy needs --city atlas|flat");
        StillRequest still{camera, imagery, args->out, args->stats, args->accuracy, args->cityAccuracy};
        still.cityAccuracyAgainst = *city::parseCityMode(args->cityAccuracyAgainst);
        auto info = renderStills(*scene, w, h, {still}, settings);
        if (!info) return fail(info.message());
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        std::printf("wrote %s (%dx%d%s, %s, %s renderer%s, %s: %s) camera %s in %.2f s\n", args->out.c_str(), w, h,
                    args->supersample > 1 ? (", " + std::to_string(args->supersample) + "x" +
                                             std::to_string(args->supersample) + " samples a pixel").c_str()
                                          : "",
                    args->imagery.view.c_str(), args->clipmap.renderer.c_str(),
                    settings.renderer == RendererKind::Clipmap ? (", centers " + args->clipmap.centers).c_str() : "",
                    info->platform.c_str(), info->renderer.c_str(), camera.toString().c_str(), s);
        return 0;
    };
}

} // namespace seasonview::app
