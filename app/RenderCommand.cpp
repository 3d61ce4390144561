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
    std::string camera, size = "1280x720", view = "leafon", out, renderer = "clipmap", centers = "footprint", stats, accuracy;
    float blend = 0.5f, swipe = 0.5f, aniso = 8.0f, shade = 0.0f;
    int clipSize = 2048, gridSize = 255, clipLevels = 0;
    bool window = false;
    std::string canopyLayers = "16", method = "default", groundUnder = "leafoff", groundElsewhere = "leafon";
    std::string trunks = "on", canopyDraw = "march";
    CityArgs city;
    std::string cityAccuracy;
    std::string terrain = "on";
    std::string terrainShading = "deferred";
    int k = kSegDefaultK;
};
} // namespace

namespace {

// The render and imagery settings of the options, checked in the order the options are listed: the first problem
// as one line naming its option.
Status renderSettingsFrom(const RenderArgs& a, RenderSettings& settings, ImagerySettings& imagery) {
    const auto view = parseImageryView(a.view);
    if (!view) return Error{"--view '" + a.view + "': expected leafon|leafoff|blend|swipe|lod|wireframe|levels|relief|canopy"};
    imagery.view = *view;
    imagery.blend = a.blend;
    imagery.swipe = a.swipe;
    imagery.anisotropy = a.aniso;
    imagery.shading = a.shade;
    if (auto st = parseCanopyGround(a.groundUnder, a.groundElsewhere, imagery); !st)
        return Error{st.message()};
    if (a.gridSize < 31 || a.gridSize > 1023 || ((a.gridSize + 1) & a.gridSize) != 0)
        return Error{"--grid-size " + std::to_string(a.gridSize) + ": expected 2^k - 1 in 31..1023"};
    settings.geometry.n = a.gridSize;
    settings.referenceAnisotropy = a.aniso;
    if (a.renderer == "reference") settings.renderer = RendererKind::Reference;
    else if (a.renderer != "clipmap") return Error{"--renderer '" + a.renderer + "': expected clipmap|reference"};
    const auto centers = parsePlacement(a.centers);
    if (!centers) return Error{"--centers '" + a.centers + "': expected " + placementNames()};
    settings.centers = *centers;
    if (a.clipSize < 256 || a.clipSize > 4096 || a.clipSize % 64 != 0)
        return Error{"--clip-size " + std::to_string(a.clipSize) + ": expected 256..4096, a multiple of 64"};
    settings.clipmap.size = a.clipSize;
    settings.clipmap.minClipLevels = a.clipLevels;
    settings.windowed = a.window;
    if (auto c = parseCanopyArgs(a.canopyLayers, a.method, a.k); !c) return Error{c.message()};
    else settings.canopy = *c;
    if (auto st = parseTrunksArg(a.trunks, settings.canopy); !st) return Error{st.message()};
    if (auto st = parseCanopyDrawArg(a.canopyDraw, settings.canopy); !st) return Error{st.message()};
    settings.cacheDir = a.scene.cache.empty() ? defaultCacheDir() : std::filesystem::path(a.scene.cache);
    if (settings.renderer == RendererKind::Reference && view != ImageryView::LeafOn && view != ImageryView::LeafOff)
        return Error{"--view " + a.view + " needs --renderer clipmap"};
    if (!a.stats.empty() && settings.renderer == RendererKind::Reference)
        return Error{"--stats needs --renderer clipmap"};
    if (!a.accuracy.empty() && settings.renderer == RendererKind::Reference)
        return Error{"--accuracy needs --renderer clipmap"};
    auto citySettings = a.city.settings();
    if (!citySettings) return Error{citySettings.message()};
    settings.city = *citySettings;
    if (settings.city) settings.city->anisotropy = a.aniso;
    if (settings.city && settings.renderer == RendererKind::Reference) return Error{"--city needs --renderer clipmap"};
    imagery.terrain = a.terrain != "off";
    imagery.path = *parseTerrainShading(a.terrainShading); // checked by CLI::IsMember
    if (!imagery.terrain) {
        if (!settings.city) return Error{"--terrain off draws only the city: give --city atlas|original|flat"};
        if (*view == ImageryView::Canopy) return Error{"--terrain off: the canopy is drawn with the terrain, not without"};
        if (!a.accuracy.empty()) return Error{"--terrain off: --accuracy compares the terrain, which is not drawn"};
    }
    return Ok{};
}

} // namespace

Runner addRenderCommand(CLI::App& app) {
    auto args = std::make_shared<RenderArgs>();
    CLI::App* cmd = app.add_subcommand("render", "Render one still of a scene to PNG/TIFF (headless by default)");
    args->scene.addTo(*cmd);
    cmd->add_option("--camera", args->camera,
                    "X,Y,Z,YAW,PITCH[,FOV]: local metres (x east, y north, z up; Z may be +H = H m above the "
                    "terrain), yaw = heading in degrees (0 north, clockwise), pitch in degrees (-90 down), fov "
                    "vertical degrees (default 60). Default: straight down over the whole scene");
    cmd->add_option("--size", args->size, "Image size WxH")->capture_default_str();
    cmd->add_option("--view", args->view, "What to show: leafon|leafoff|blend|swipe|lod|wireframe|levels|relief|canopy")->capture_default_str();
    cmd->add_option("--blend", args->blend, "blend view: 0 = leaf-on .. 1 = leaf-off")->capture_default_str();
    cmd->add_option("--swipe", args->swipe, "swipe view: fraction of the width showing leaf-on")->capture_default_str();
    cmd->add_option("--aniso", args->aniso,
                    "Maximum anisotropy, 1..16 (1 = isotropic): probes per pixel of the clipmap's footprint filter; "
                    "the reference renderer's sampler anisotropy")
        ->check(CLI::Range(1.0f, kMaxAnisotropy))
        ->capture_default_str();
    cmd->add_option("--shade", args->shade, "Lambert shading of the relief from the elevation's normals, 0..1")
        ->check(CLI::Range(0.0f, 1.0f))
        ->capture_default_str();
    cmd->add_option("--grid-size", args->gridSize,
                    "Geometry clipmap: vertices per level side n = 2^k - 1 (31..1023)")
        ->capture_default_str();
    cmd->add_option("--renderer", args->renderer,
                    "Renderer: clipmap (streamed texture clipmaps) | reference (brute force, full-resolution textures)")
        ->capture_default_str();
    cmd->add_option("--centers", args->centers, "Clipmap level centres: " + placementNames())->capture_default_str();
    cmd->add_option("--clip-size", args->clipSize, "Clipmap level size N, texels (256..4096, multiple of 64)")
        ->capture_default_str();
    cmd->add_option("--accuracy", args->accuracy,
                    "Also render the reference and write PSNR and geometric accuracy (mean depth difference in "
                    "screen pixels) to this JSON file");
    cmd->add_option("--clip-levels", args->clipLevels,
                    "Toroidal clipmap levels allocated at least (0 = as the image needs; fixed = same memory for "
                    "every image)")
        ->check(CLI::Range(0, 16))
        ->capture_default_str();
    cmd->add_option("--canopy-layers", args->canopyLayers,
                    "canopy view: stacked canopy layers, 1..32, or off (the ground alone: leaf-off under the crowns)")
        ->capture_default_str();
    cmd->add_option("--method", args->method,
                    "canopy view: segmentation method of the canopy layer, pixel|neighborhood|equalized|default")
        ->capture_default_str();
    cmd->add_option("--k", args->k, "canopy view: neighbourhood size of the ground layer (odd, 1..15)")
        ->capture_default_str();
    cmd->add_option("--trunks", args->trunks,
                    "canopy view: trunks at the crown centres found in the canopy layer, the crowns lifted to their "
                    "base; on|off")
        ->capture_default_str();
    cmd->add_option("--canopy-draw", args->canopyDraw,
                    "canopy view: how the stacked layers are drawn: march (the top layer rasterised, each pixel's ray "
                    "intersected with the layers below) or layers (every layer rasterised, §4.2 as written); layers|march")
        ->capture_default_str();
    cmd->add_option("--ground-under-canopy", args->groundUnder,
                    "canopy view: season of the ground under the crowns (seen where layers are off), leafon|leafoff")
        ->capture_default_str();
    cmd->add_option("--ground-elsewhere", args->groundElsewhere,
                    "canopy view: season of the ground away from the crowns, leafon|leafoff")
        ->capture_default_str();
    cmd->add_option("--stats", args->stats, "Write level statistics (coverage, uploads, memory) to this JSON file");
    cmd->add_option("--out", args->out, "Output image (.png or .tif)")->required();
    cmd->add_flag("--window", args->window, "Render through a hidden GLFW window instead of headless EGL");
    args->city.addTo(*cmd);
    cmd->add_option("--city-accuracy", args->cityAccuracy,
                    "With --city: write the city's PSNR against its original textures (same view) to this JSON");
    cmd->add_option("--terrain-shading", args->terrainShading,
                    "How the terrain's fragments are shaded: deferred (a geometry pass, then each pixel once) or "
                    "forward (as rasterised); the same pixels")
        ->check(CLI::IsMember({"forward", "deferred"}))
        ->capture_default_str();
    cmd->add_option("--terrain", args->terrain, "on: the terrain drawn; off: only the city (needs --city)")
        ->check(CLI::IsMember({"on", "off"}))
        ->capture_default_str();
    return [args]() -> int {
        const auto t0 = std::chrono::steady_clock::now();
        auto fail = [](const std::string& m) {
            std::fprintf(stderr, "seasonview render: %s\n", m.c_str());
            return 1;
        };
        RenderSettings settings;
        ImagerySettings imagery;
        if (auto st = renderSettingsFrom(*args, settings, imagery); !st) return fail(st.message());
        auto size = parseSize(args->size);
        if (!size) return fail(size.message());
        if (auto st = checkImageOutput(args->out); !st) return fail(st.message());
        std::optional<CameraSpec> spec;
        if (!args->camera.empty()) {
            auto parsed = parseCamera(args->camera);
            if (!parsed) return fail(parsed.message());
            spec = *parsed;
        }
        auto scene = args->scene.load();
        if (!scene) return fail(scene.message());
        printSceneNotes(*scene);
        if (settings.city) {
            auto tree = prepareCityTree(*scene, settings.cacheDir, args->city.tree);
            if (!tree) return fail(tree.message());
            settings.cityTree = *tree;
        }
        const auto [w, h] = *size;
        const Camera camera = spec ? spec->resolve([&](double x, double y) { return scene->terrainHeight(x, y); })
                                   : overviewCamera(*scene, double(w) / double(h));
        if (!args->cityAccuracy.empty() && !settings.city) return fail("--city-accuracy needs --city atlas|flat");
        auto info = renderStills(*scene, w, h, {{camera, imagery, args->out, args->stats, args->accuracy, args->cityAccuracy}},
                                 settings);
        if (!info) return fail(info.message());
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        std::printf("wrote %s (%dx%d, %s, %s renderer%s, %s: %s) camera %s in %.2f s\n", args->out.c_str(), w, h,
                    args->view.c_str(), args->renderer.c_str(),
                    settings.renderer == RendererKind::Clipmap ? (", centers " + args->centers).c_str() : "",
                    info->platform.c_str(), info->renderer.c_str(), camera.toString().c_str(), s);
        return 0;
    };
}

} // namespace seasonview::app
