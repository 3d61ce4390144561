// `seasonview render`: one still of a scene.
#include "Commands.h"
#include "RenderJob.h"

#include <chrono>
#include <cstdio>
#include <memory>

namespace seasonview::app {

namespace {
struct RenderArgs {
    SceneArgs scene;
    std::string camera, size = "1280x720", view = "leafon", out, renderer = "reference";
    bool window = false;
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
    cmd->add_option("--view", args->view, "What to show: leafon|leafoff")->capture_default_str();
    cmd->add_option("--renderer", args->renderer, "Renderer: reference")->capture_default_str();
    cmd->add_option("--out", args->out, "Output image (.png or .tif)")->required();
    cmd->add_flag("--window", args->window, "Render through a hidden GLFW window instead of headless EGL");
    return [args]() -> int {
        const auto t0 = std::chrono::steady_clock::now();
        auto fail = [](const std::string& m) {
            std::fprintf(stderr, "seasonview render: %s\n", m.c_str());
            return 1;
        };
        Season season;
        if (args->view == "leafon") season = Season::LeafOn;
        else if (args->view == "leafoff") season = Season::LeafOff;
        else return fail("--view '" + args->view + "': expected leafon|leafoff");
        if (args->renderer != "reference") return fail("--renderer '" + args->renderer + "': expected reference");
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
        const auto [w, h] = *size;
        const Camera camera = spec ? spec->resolve([&](double x, double y) { return scene->terrainHeight(x, y); })
                                   : overviewCamera(*scene, double(w) / double(h));
        auto info = renderStills(*scene, w, h, {{camera, season, args->out}}, args->window);
        if (!info) return fail(info.message());
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        std::printf("wrote %s (%dx%d, %s, reference renderer, %s: %s) camera %s in %.2f s\n", args->out.c_str(), w, h,
                    args->view.c_str(), info->platform.c_str(), info->renderer.c_str(), camera.toString().c_str(), s);
        return 0;
    };
}

} // namespace seasonview::app
