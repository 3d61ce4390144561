// `seasonview view`: the interactive viewer (Viewer.h). This file declares its options and checks them before a
// window opens; `--script`, `--screenshot-at` and `--quit-at` run it without a person, and with any of them the clock
// advances by a fixed step per frame (`--fixed-dt`), so what a script does does not depend on how fast the machine
// draws.
#include "CityJob.h"
#include "Commands.h"
#include "RenderJob.h"
#include "Viewer.h"
#include "ViewerInput.h"

#include <algorithm>
#include <cstdio>
#include <memory>

namespace seasonview::app {

namespace {

struct ViewArgs {
    SceneArgs scene;
    FrameArgs frame;
    ImageryArgs imagery;
    ClipmapArgs clipmap;
    CanopyArgs canopy;
    CityArgs city;
    std::string mode, script, record, bookmarks, screenshotDir = ".", screenshotSize;
    std::vector<std::string> screenshotsAt, windowShotsAt;
    double quitAt = -1.0, fixedDt = -1.0;
    bool noPanel = false;
};

// The viewer's options beyond the shared groups: navigation, scripts, screenshots, recording, bookmarks.
void addViewerOptions(CLI::App& cmd, ViewArgs& a) {
    const char* group = "Viewer";
    cmd.add_option("--mode", a.mode, "Navigation: map | fly | orbit (default: map when looking straight down)")
        ->group(group);
    cmd.add_option("--script", a.script, "Replay timed input events from a JSON file (see app/README.md)")->group(group);
    cmd.add_option("--screenshot-at", a.screenshotsAt, "T:FILE: save the view at T seconds (repeatable)")->group(group);
    cmd.add_option("--window-screenshot-at", a.windowShotsAt,
                   "T:FILE: save the whole window, panel included, at T seconds (repeatable)")
        ->group(group);
    cmd.add_option("--quit-at", a.quitAt, "Exit at T seconds")->group(group);
    cmd.add_option("--fixed-dt", a.fixedDt,
                   "Seconds the clock advances per frame (default 1/30 with --script, --screenshot-at or --quit-at; "
                   "otherwise real time)")
        ->group(group);
    cmd.add_option("--record", a.record, "Record the flown camera as a bench path JSON (keyframes every 0.25 s)")
        ->group(group);
    cmd.add_option("--bookmarks", a.bookmarks, "Camera bookmarks file (JSON array of camera strings): K adds, J jumps")
        ->group(group);
    cmd.add_option("--screenshot-dir", a.screenshotDir, "Folder of P's screenshots")->capture_default_str()->group(group);
    cmd.add_option("--screenshot-size", a.screenshotSize, "Size WxH of P's screenshots (default: the window's)")
        ->group(group);
    cmd.add_flag("--no-panel", a.noPanel, "Start with the settings panel hidden (H toggles it)")->group(group);
}

// The panel's first state from the shared options.
Result<ViewerSettings> viewerSettings(const ViewArgs& a) {
    ViewerSettings s;
    if (auto st = a.imagery.apply(s.imagery); !st) return st.error();
    if (auto st = a.canopy.applyGround(s.imagery); !st) return st.error();
    auto canopy = a.canopy.settings();
    if (!canopy) return canopy.error();
    s.layers = canopy->layers;
    s.params = canopy->params;
    s.trunks = canopy->trunks;
    s.marchLayers = canopy->draw == CanopyDrawMode::March;
    s.canopyLevelsRead = canopy->levelsRead;
    s.canopyDerivation = canopy->derivation;
    auto centers = a.clipmap.placement();
    if (!centers) return centers.error();
    s.centers = *centers;
    s.panel = !a.noPanel;
    return s;
}

// --screenshot-at / --window-screenshot-at values, checked and sorted by time.
Result<std::vector<TimedScreenshot>> timedScreenshots(const std::vector<std::string>& values, const std::string& flag) {
    std::vector<TimedScreenshot> shots;
    for (const std::string& t : values) {
        auto sh = parseTimedScreenshot(t);
        if (!sh) return Error{flag == "--screenshot-at" ? sh.message() : "--window-" + sh.message().substr(2)};
        if (auto st = checkImageOutput(sh->file); !st) return st.error();
        shots.push_back(*sh);
    }
    std::sort(shots.begin(), shots.end(), [](auto& x, auto& y) { return x.t < y.t; });
    return shots;
}

// Everything but the scene: the checks that need no file read beyond the script and bookmarks.
Status viewerOptions(const ViewArgs& a, ViewerOptions& o) {
    auto size = a.frame.frameSize();
    if (!size) return size.error();
    o.size = *size;
    auto settings = viewerSettings(a);
    if (!settings) return settings.error();
    o.settings = *settings;
    if (auto st = a.clipmap.check(); !st) return st;
    o.clipSize = a.clipmap.clipSize;
    o.clipLevels = a.clipmap.clipLevels;
    o.gridSize = a.clipmap.gridSize;
    if (!a.mode.empty()) {
        if (a.mode == "map") o.mode = NavMode::Map;
        else if (a.mode == "fly") o.mode = NavMode::Fly;
        else if (a.mode == "orbit") o.mode = NavMode::Orbit;
        else return Error{"--mode '" + a.mode + "': expected map, fly or orbit"};
    }
    if (!a.script.empty()) {
        auto sc = loadViewerScript(a.script);
        if (!sc) return sc.error();
        o.script = std::move(*sc);
        o.scriptName = a.script;
        for (const ScriptEvent& e : o.script)
            if ((e.kind == ScriptEvent::Kind::Key || e.kind == ScriptEvent::Kind::Hold) && !keyCode(e.key))
                return Error{a.script + ": unknown key '" + e.key + "'"};
    }
    auto shots = timedScreenshots(a.screenshotsAt, "--screenshot-at");
    if (!shots) return shots.error();
    o.shots = std::move(*shots);
    auto windowShots = timedScreenshots(a.windowShotsAt, "--window-screenshot-at");
    if (!windowShots) return windowShots.error();
    o.windowShots = std::move(*windowShots);
    if (!a.screenshotSize.empty()) {
        auto ss = parseSize(a.screenshotSize);
        if (!ss) return ss.error();
        o.shotSize = *ss;
    }
    o.screenshotDir = a.screenshotDir;
    auto bookmarks = loadBookmarks(a.bookmarks);
    if (!bookmarks) return bookmarks.error();
    o.bookmarks = std::move(*bookmarks);
    o.scripted = !o.script.empty() || !o.shots.empty() || !o.windowShots.empty() || a.quitAt >= 0.0;
    o.fixedDt = a.fixedDt > 0.0 ? a.fixedDt : (o.scripted ? 1.0 / 30.0 : 0.0);
    o.quitAt = a.quitAt;
    o.record = a.record;
    o.cache = a.scene.cacheDir();
    auto city = a.city.settings();
    if (!city) return city.error();
    o.city = *city;
    if (o.city) o.city->anisotropy = o.settings.imagery.anisotropy;
    if (!o.settings.imagery.terrain) {
        if (!o.city) return Error{"--terrain off draws only the city: give --city atlas|original|flat"};
        if (o.settings.imagery.view == ImageryView::Canopy)
            return Error{"--terrain off: the canopy is drawn with the terrain, not without"};
    }
    return Ok{};
}

} // namespace

Runner addViewCommand(CLI::App& app) {
    auto a = std::make_shared<ViewArgs>();
    a->clipmap.clipSize = 1024;
    CLI::App* cmd = app.add_subcommand("view", "Interactive viewer: fly over the scene and compare the seasons (GLFW window)");
    a->scene.addTo(*cmd);
    a->frame.addTo(*cmd, "Window", {.camera = true, .window = false});
    a->imagery.addTo(*cmd);
    a->clipmap.addTo(*cmd, false);
    a->canopy.addTo(*cmd);
    a->city.addTo(*cmd);
    addViewerOptions(*cmd, *a);
    return [a]() -> int {
        auto fail = [](const std::string& m) {
            std::fprintf(stderr, "seasonview view: %s\n", m.c_str());
            return 1;
        };
        ViewerOptions o;
        if (auto st = viewerOptions(*a, o); !st) return fail(st.message());
        auto scene = a->scene.load();
        if (!scene) return fail(scene.message());
        printSceneNotes(*scene);
        if (o.city) {
            auto t = prepareCityTree(*scene, o.cache, a->city.tree);
            if (!t) return fail(t.message());
            o.cityTree = *t;
        }
        o.start = overviewCamera(*scene, double(o.size.first) / double(o.size.second));
        auto spec = a->frame.cameraSpec();
        if (!spec) return fail("--camera: " + spec.message());
        if (*spec) o.start = (*spec)->resolve([&](double x, double y) { return scene->terrainHeight(x, y); });
        return runViewer(*scene, std::move(o));
    };
}

} // namespace seasonview::app
