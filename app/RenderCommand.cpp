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
        const auto view = parseImageryView(args->view);
        if (!view) return fail("--view '" + args->view + "': expected leafon|leafoff|blend|swipe|lod|wireframe|levels|relief|canopy");
        imagery.view = *view;
        imagery.blend = args->blend;
        imagery.swipe = args->swipe;
        imagery.anisotropy = args->aniso;
        imagery.shading = args->shade;
        if (auto st = parseCanopyGround(args->groundUnder, args->groundElsewhere, imagery); !st)
            return fail(st.message());
        if (args->gridSize < 31 || args->gridSize > 1023 || ((args->gridSize + 1) & args->gridSize) != 0)
            return fail("--grid-size " + std::to_string(args->gridSize) + ": expected 2^k - 1 in 31..1023");
        settings.geometry.n = args->gridSize;
        settings.referenceAnisotropy = args->aniso;
        if (args->renderer == "reference") settings.renderer = RendererKind::Reference;
        else if (args->renderer != "clipmap") return fail("--renderer '" + args->renderer + "': expected clipmap|reference");
        const auto centers = parsePlacement(args->centers);
        if (!centers) return fail("--centers '" + args->centers + "': expected " + placementNames());
        settings.centers = *centers;
        if (args->clipSize < 256 || args->clipSize > 4096 || args->clipSize % 64 != 0)
            return fail("--clip-size " + std::to_string(args->clipSize) + ": expected 256..4096, a multiple of 64");
        settings.clipmap.size = args->clipSize;
        settings.clipmap.minClipLevels = args->clipLevels;
        settings.windowed = args->window;
        if (auto c = parseCanopyArgs(args->canopyLayers, args->method, args->k); !c) return fail(c.message());
        else settings.canopy = *c;
        if (auto st = parseTrunksArg(args->trunks, settings.canopy); !st) return fail(st.message());
        if (auto st = parseCanopyDrawArg(args->canopyDraw, settings.canopy); !st) return fail(st.message());
        settings.cacheDir = args->scene.cache.empty() ? defaultCacheDir() : std::filesystem::path(args->scene.cache);
        if (settings.renderer == RendererKind::Reference && view != ImageryView::LeafOn && view != ImageryView::LeafOff)
            return fail("--view " + args->view + " needs --renderer clipmap");
        if (!args->stats.empty() && settings.renderer == RendererKind::Reference)
            return fail("--stats needs --renderer clipmap");
        if (!args->accuracy.empty() && settings.renderer == RendererKind::Reference)
            return fail("--accuracy needs --renderer clipmap");
        auto citySettings = args->city.settings();
        if (!citySettings) return fail(citySettings.message());
        settings.city = *citySettings;
        if (settings.city) settings.city->anisotropy = args->aniso;
        if (settings.city && settings.renderer == RendererKind::Reference) return fail("--city needs --renderer clipmap");
        imagery.terrain = args->terrain != "off";
        imagery.path = *parseTerrainShading(args->terrainShading); // checked by CLI::IsMember
        if (!imagery.terrain) {
            if (!settings.city) return fail("--terrain off draws only the city: give --city atlas|original|flat");
            if (*view == ImageryView::Canopy) return fail("--terrain off: the canopy is drawn with the terrain, not without");
            if (!args->accuracy.empty()) return fail("--terrain off: --accuracy compares the terrain, which is not drawn");
        }
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
