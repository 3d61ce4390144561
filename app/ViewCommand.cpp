// `seasonview view`: the interactive viewer. A GLFW window (also under Xvfb) showing the scene through the same
// renderers as `render` and `bench`, a Dear ImGui panel with the settings, a HUD, navigation (core/camera/CameraControl.h:
// map, fly, orbit), screenshots, camera bookmarks, and recording the flown camera as a bench path. `--script`,
// `--screenshot-at` and `--quit-at` run it without a person (ViewerScript.h); with any of them the clock advances by
// a fixed step per frame (`--fixed-dt`), so what a script does does not depend on how fast the machine draws.
#include "AtomicFile.h"
#include "JsonFile.h"
#include "CameraControl.h"
#include "CityJob.h"
#include "Commands.h"
#include "RenderJob.h"
#include "SeasonCoverage.h"
#include "ViewerScript.h"
#include "gl/GlDebug.h"

#include "CanopyClipmapGL.h"
#include "CanopyRendererGL.h"
#include "TrunksGL.h"

#include <epoxy/gl.h>
#ifndef GLFW_INCLUDE_NONE
#define GLFW_INCLUDE_NONE
#endif
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <set>

namespace seasonview::app {

namespace {

struct ViewArgs {
    SceneArgs scene;
    std::string size = "1280x720", camera, mode, script, record, bookmarks, screenshotDir = ".", screenshotSize;
    std::vector<std::string> screenshotsAt, windowShotsAt;
    double quitAt = -1.0, fixedDt = -1.0;
    int clipSize = 1024, gridSize = 255;
    std::string view = "leafon", canopyLayers = "16", method = "default", trunks = "on", centers = "footprint";
    std::string canopyDraw = "march";
    int k = kSegDefaultK;
    bool noPanel = false;
    CityArgs city;
};

// Key names for scripts and the help text -> GLFW key codes.
std::optional<int> keyCode(const std::string& name) {
    if (name.size() == 1) {
        const char c = char(std::toupper(static_cast<unsigned char>(name[0])));
        if (c >= 'A' && c <= 'Z') return GLFW_KEY_A + (c - 'A');
        if (c >= '0' && c <= '9') return GLFW_KEY_0 + (c - '0');
    }
    static const std::map<std::string, int> named = {
        {"Space", GLFW_KEY_SPACE}, {"Tab", GLFW_KEY_TAB},     {"Shift", GLFW_KEY_LEFT_SHIFT},
        {"Escape", GLFW_KEY_ESCAPE}, {"Up", GLFW_KEY_UP},     {"Down", GLFW_KEY_DOWN},
        {"Left", GLFW_KEY_LEFT},    {"Right", GLFW_KEY_RIGHT}};
    if (auto it = named.find(name); it != named.end()) return it->second;
    return std::nullopt;
}

// What the panel edits (and `set` events in scripts).
struct ViewerSettings {
    ImageryView view = ImageryView::LeafOn;
    float blend = 0.5f, swipe = 0.5f, shading = 0.0f;
    int layers = 16; // 0: off
    bool trunks = true;
    bool marchLayers = true; // CanopyDrawMode::March (false: every layer rasterised)
    CenterPlacement centers = CenterPlacement::Footprint;
    SegmentationParams params{SegmentationMethod::Default, kSegDefaultK};
    bool panel = true;
    int coverageEvery = 30; // frames between coverage measurements (0: never)
    bool city = true;       // the city model, when the viewer was started with one (key B)
    float cityTpp = 1.0f;   // its pixels per texel
};

// Keys 1..9.
const char* kViewKeys[] = {"leafon", "leafoff", "blend", "swipe", "canopy", "lod", "levels", "wireframe", "relief"};

// The scene on the GPU: clipmaps, terrain, canopy, trunks, as `render` and `bench` make them.
struct LiveScene {
    const Scene* scene = nullptr;
    std::vector<ImagePyramid> pyramids;
    std::optional<SeasonCoverageProbe> coverage; // which season has data under the cursor (HUD)
    std::optional<ImagePyramid> elevation;
    std::optional<SegmentationHistograms> histograms;
    std::filesystem::path cache;
    std::unique_ptr<ClipmapGL> clip;
    std::unique_ptr<ClipmapTerrainRendererGL> terrain;
    std::unique_ptr<CanopyClipmapGL> canopy;
    std::unique_ptr<CanopyRendererGL> canopyRenderer;
    std::unique_ptr<TrunksGL> trunks;
    SegmentationParams canopyParams{};
    int canopyLayers = -1;
    bool canopyTrunks = false;
    ClipmapFrameStats lastLoad;
    std::int64_t texelsTotal = 0;
    bool damagedReported = false;
    std::unique_ptr<city::CityRendererGL> city;
    city::CityFrameStats cityStats;

    // (Re)makes the canopy when its rule, layer count or trunks changed (the derived layer is recomputed).
    Status ensureCanopy(const ViewerSettings& s) {
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
        auto c = CanopyClipmapGL::create(*clip, statsFromHistograms(*histograms, co.params.method), co);
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
        }
        canopyParams = s.params;
        canopyLayers = layers;
        canopyTrunks = wantTrunks;
        return Ok{};
    }

    // One frame into `target`. `complete`: wait for every texel the view needs (screenshots).
    GeometryFrameStats draw(const Camera& cam, const ViewerSettings& s, const gl::RenderTarget& target, bool complete) {
        const int w = target.width(), h = target.height();
        const ClipmapGeometry g = clipmapGeometry(*scene, clip->schedule().layout());
        lastLoad = clip->update(clipmapCentres(*scene, cam, w, h, s.centers, g));
        texelsTotal += lastLoad.texelsUploaded;
        if (const auto& e = clip->readError(); e && !damagedReported) {
            // Never drawn (coarser levels stand in); the pyramid is rebuilt on the next start.
            invalidateDamagedPyramid(e->message, cache);
            damagedReported = true;
            std::fprintf(stderr, "seasonview view: %s (damaged in the cache: drawn from coarser levels, rebuilt from "
                                 "the source on the next start)\n", e->message.c_str());
        }
        terrain->updateGeometry(cam, h);
        if (complete) {
            const ClipmapFrameStats more = clip->completeSynchronously();
            texelsTotal += more.texelsUploaded;
            terrain->completeGeometry();
        }
        const bool canopyView = s.view == ImageryView::Canopy;
        if (canopyView && canopy) {
            if (complete) {
                canopy->completeSynchronously();
                if (trunks) trunks->find();
            } else {
                canopy->update();
                if (trunks) trunks->update();
            }
        }
        ImagerySettings im;
        im.view = s.view;
        im.blend = s.blend;
        im.swipe = s.swipe;
        im.shading = s.shading;
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
            city->settings().roofs = city::roofImageryFor(im);
            if (complete) city->complete(cam, target.width(), target.height());
            else city->update(cam, target.width(), target.height());
            cityStats = city->draw(cam, terrain.get(), target);
            drawn.triangles += cityStats.triangles;
            drawn.drawCalls += cityStats.drawCalls;
        }
        return drawn;
    }

    std::int64_t residentBytes() const { return clip->residentBytes() + (canopy ? canopy->residentBytes() : 0); }
};

// Applies a `set` event or a panel change given by name; false (and a message) for an unknown name or value.
bool applySetting(ViewerSettings& s, const std::string& name, const nlohmann::json& v, std::string& err) {
    auto str = [&]() { return v.is_string() ? v.get<std::string>() : v.dump(); };
    if (name == "view") {
        auto view = parseImageryView(str());
        if (!view) return err = "view '" + str() + "' unknown", false;
        s.view = *view;
    } else if (name == "blend" && v.is_number()) {
        s.blend = std::clamp(v.get<float>(), 0.0f, 1.0f);
    } else if (name == "swipe" && v.is_number()) {
        s.swipe = std::clamp(v.get<float>(), 0.0f, 1.0f);
    } else if (name == "shading" && v.is_number()) {
        s.shading = std::clamp(v.get<float>(), 0.0f, 1.0f);
    } else if (name == "layers") {
        if (v.is_string() && v.get<std::string>() == "off") s.layers = 0;
        else if (v.is_number_integer() && v.get<int>() >= 1 && v.get<int>() <= 64) s.layers = v.get<int>();
        else return err = "layers must be 1..64 or \"off\"", false;
    } else if (name == "city" && v.is_boolean()) {
        s.city = v.get<bool>();
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

// Window input gathered by the GLFW callbacks between frames.
struct WindowInput {
    glm::dvec2 cursor{0.0};
    glm::dvec2 drag{0.0};
    double wheel = 0.0;
    bool buttons[2] = {false, false};
    bool pressedButton[2] = {false, false}; // went down since the last frame
    glm::dvec2 pressedAt[2] = {glm::dvec2(0.0), glm::dvec2(0.0)};
    std::set<int> held;
    std::vector<int> pressedKeys;
};

WindowInput* inputOf(GLFWwindow* w) { return static_cast<WindowInput*>(glfwGetWindowUserPointer(w)); }

void onCursor(GLFWwindow* w, double x, double y) {
    WindowInput* in = inputOf(w);
    if (ImGui::GetCurrentContext() && ImGui::GetIO().WantCaptureMouse && !in->buttons[0] && !in->buttons[1]) {
        in->cursor = {x, y};
        return;
    }
    if (in->buttons[0] || in->buttons[1]) in->drag += glm::dvec2(x, y) - in->cursor;
    in->cursor = {x, y};
}
void onButton(GLFWwindow* w, int button, int action, int) {
    WindowInput* in = inputOf(w);
    if (button > 1) return;
    if (action == GLFW_PRESS && ImGui::GetCurrentContext() && ImGui::GetIO().WantCaptureMouse) return;
    in->buttons[button] = action == GLFW_PRESS;
    if (action == GLFW_PRESS) {
        in->pressedButton[button] = true;
        in->pressedAt[button] = in->cursor;
    }
}
void onScroll(GLFWwindow* w, double, double dy) {
    if (ImGui::GetCurrentContext() && ImGui::GetIO().WantCaptureMouse) return;
    inputOf(w)->wheel += dy;
}
void onKey(GLFWwindow* w, int key, int, int action, int) {
    WindowInput* in = inputOf(w);
    if (ImGui::GetCurrentContext() && ImGui::GetIO().WantCaptureKeyboard) return;
    if (action == GLFW_PRESS) {
        in->held.insert(key);
        in->pressedKeys.push_back(key);
    } else if (action == GLFW_RELEASE)
        in->held.erase(key);
}

struct Bookmarks {
    std::filesystem::path file; // empty: kept in memory only
    std::vector<Camera> cameras;
    size_t next = 0;
};

Result<Bookmarks> loadBookmarks(const std::string& file) {
    Bookmarks b;
    b.file = file;
    std::error_code ec;
    if (file.empty() || !std::filesystem::exists(file, ec)) return b;
    auto parsed = readJsonFile(file, "bookmarks");
    if (!parsed) return parsed.error();
    const nlohmann::json& j = *parsed;
    if (!j.is_array()) return fileError(file, "bookmarks must be a JSON array of camera strings");
    for (size_t i = 0; i < j.size(); ++i) {
        if (!j[i].is_string()) return fileError(file, "bookmark " + std::to_string(i) + " is not a camera string");
        auto c = parseCamera(j[i].get<std::string>());
        if (!c) return fileError(file, "bookmark " + std::to_string(i) + ": " + c.message());
        b.cameras.push_back(c->camera);
    }
    return b;
}

Status saveBookmarks(const Bookmarks& b) {
    if (b.file.empty()) return Ok{};
    nlohmann::json j = nlohmann::json::array();
    for (const Camera& c : b.cameras) j.push_back(c.toString());
    std::string err;
    if (!writeTextAtomic(b.file, j.dump(2) + "\n", err)) return fileError(b.file.string(), err);
    return Ok{};
}

// The flown camera as bench keyframes, one every `step` seconds of the viewer's clock.
struct Recorder {
    std::filesystem::path file;
    bool on = false;
    double step = 0.25, start = 0.0, lastT = -1e9;
    nlohmann::json keys = nlohmann::json::array();
    int frameStep = 0; // fixed clock: a keyframe every this many frames (uniform keyframe times)
    int frames = 0;
    void add(double t, const Camera& c) {
        if (!on) return;
        const bool due = frameStep > 0 ? frames++ % frameStep == 0 : t - lastT >= step - 1e-9;
        if (!due) return;
        lastT = t;
        keys.push_back({{"time", t - start},
                        {"x", c.position.x},
                        {"y", c.position.y},
                        {"z", c.position.z},
                        {"yaw", c.yawDeg},
                        {"pitch", c.pitchDeg},
                        {"fov", c.fovYDeg}});
    }
    Status save() const {
        if (file.empty() || keys.size() < 2) return Ok{};
        std::string err;
        if (!writeTextAtomic(file, keys.dump(1) + "\n", err)) return fileError(file.string(), err);
        return Ok{};
    }
};

} // namespace

Runner addViewCommand(CLI::App& app) {
    auto a = std::make_shared<ViewArgs>();
    CLI::App* cmd = app.add_subcommand("view", "Interactive viewer: fly over the scene and compare the seasons (GLFW window)");
    a->scene.addTo(*cmd);
    cmd->add_option("--size", a->size, "Window size WxH")->capture_default_str();
    cmd->add_option("--camera", a->camera, "Start camera X,Y,Z,YAW,PITCH[,FOV] (Z may be +H); default: the overview");
    cmd->add_option("--mode", a->mode, "Navigation: map | fly | orbit (default: map when looking straight down)");
    cmd->add_option("--view", a->view, "Start view: leafon, leafoff, blend, swipe, lod, wireframe, levels, relief, canopy")
        ->capture_default_str();
    cmd->add_option("--canopy-layers", a->canopyLayers, "Stacked canopy layers N or off")->capture_default_str();
    cmd->add_option("--method", a->method, "Segmentation method of the canopy")->capture_default_str();
    cmd->add_option("--k", a->k, "Neighbourhood size of the canopy's rule (odd)")->capture_default_str();
    cmd->add_option("--trunks", a->trunks, "Trunks under the crowns: on | off")->capture_default_str();
    cmd->add_option("--canopy-draw", a->canopyDraw, "How the stacked layers are drawn: layers | march")
        ->capture_default_str();
    cmd->add_option("--centers", a->centers, "Clipmap level centres: concentric | offset | footprint")->capture_default_str();
    cmd->add_option("--clip-size", a->clipSize, "Clipmap level size N")->capture_default_str();
    a->city.addTo(*cmd);
    cmd->add_option("--grid-size", a->gridSize, "Geometry clipmap vertices per level side (2^k - 1)")->capture_default_str();
    cmd->add_option("--script", a->script, "Replay timed input events from a JSON file (see app/README.md)");
    cmd->add_option("--screenshot-at", a->screenshotsAt, "T:FILE: save the view at T seconds (repeatable)");
    cmd->add_option("--window-screenshot-at", a->windowShotsAt,
                    "T:FILE: save the whole window, panel included, at T seconds (repeatable)");
    cmd->add_option("--quit-at", a->quitAt, "Exit at T seconds");
    cmd->add_option("--fixed-dt", a->fixedDt,
                    "Seconds the clock advances per frame (default 1/30 with --script, --screenshot-at or --quit-at; "
                    "otherwise real time)");
    cmd->add_option("--record", a->record, "Record the flown camera as a bench path JSON (keyframes every 0.25 s)");
    cmd->add_option("--bookmarks", a->bookmarks, "Camera bookmarks file (JSON array of camera strings): K adds, J jumps");
    cmd->add_option("--screenshot-dir", a->screenshotDir, "Folder of P's screenshots")->capture_default_str();
    cmd->add_option("--screenshot-size", a->screenshotSize, "Size WxH of P's screenshots (default: the window's)");
    cmd->add_flag("--no-panel", a->noPanel, "Start with the settings panel hidden (H toggles it)");
    return [a]() -> int {
        auto fail = [](const std::string& m) {
            std::fprintf(stderr, "seasonview view: %s\n", m.c_str());
            return 1;
        };
        auto size = parseSize(a->size);
        if (!size) return fail(size.message());
        ViewerSettings s;
        {
            auto v = parseImageryView(a->view);
            if (!v) return fail("--view '" + a->view + "': unknown view");
            s.view = *v;
            auto cs = parseCanopyArgs(a->canopyLayers, a->method, a->k);
            if (!cs) return fail(cs.message());
            s.layers = cs->layers;
            s.params = cs->params;
            CanopyRenderSettings tr;
            if (auto st = parseTrunksArg(a->trunks, tr); !st) return fail(st.message());
            s.trunks = tr.trunks;
            if (auto st = parseCanopyDrawArg(a->canopyDraw, tr); !st) return fail(st.message());
            s.marchLayers = tr.draw == CanopyDrawMode::March;
            auto c = parsePlacement(a->centers);
            if (!c) return fail("--centers '" + a->centers + "': expected concentric, offset or footprint");
            s.centers = *c;
            s.panel = !a->noPanel;
        }
        std::optional<NavMode> startMode;
        if (!a->mode.empty()) {
            if (a->mode == "map") startMode = NavMode::Map;
            else if (a->mode == "fly") startMode = NavMode::Fly;
            else if (a->mode == "orbit") startMode = NavMode::Orbit;
            else return fail("--mode '" + a->mode + "': expected map, fly or orbit");
        }
        std::vector<ScriptEvent> script;
        if (!a->script.empty()) {
            auto sc = loadViewerScript(a->script);
            if (!sc) return fail(sc.message());
            script = std::move(*sc);
            for (const ScriptEvent& e : script)
                if ((e.kind == ScriptEvent::Kind::Key || e.kind == ScriptEvent::Kind::Hold) && !keyCode(e.key))
                    return fail(a->script + ": unknown key '" + e.key + "'");
        }
        std::vector<TimedScreenshot> shots;
        for (const std::string& t : a->screenshotsAt) {
            auto sh = parseTimedScreenshot(t);
            if (!sh) return fail(sh.message());
            if (auto st = checkImageOutput(sh->file); !st) return fail(st.message());
            shots.push_back(*sh);
        }
        std::sort(shots.begin(), shots.end(), [](auto& x, auto& y) { return x.t < y.t; });
        std::vector<TimedScreenshot> windowShots;
        for (const std::string& t : a->windowShotsAt) {
            auto sh = parseTimedScreenshot(t);
            if (!sh) return fail("--window-" + sh.message().substr(2));
            if (auto st = checkImageOutput(sh->file); !st) return fail(st.message());
            windowShots.push_back(*sh);
        }
        std::sort(windowShots.begin(), windowShots.end(), [](auto& x, auto& y) { return x.t < y.t; });
        std::optional<std::pair<int, int>> shotSize;
        if (!a->screenshotSize.empty()) {
            auto ss = parseSize(a->screenshotSize);
            if (!ss) return fail(ss.message());
            shotSize = *ss;
        }
        auto bookmarks = loadBookmarks(a->bookmarks);
        if (!bookmarks) return fail(bookmarks.message());
        const bool scripted = !script.empty() || !shots.empty() || !windowShots.empty() || a->quitAt >= 0.0;
        const double fixedDt = a->fixedDt > 0.0 ? a->fixedDt : (scripted ? 1.0 / 30.0 : 0.0);

        auto scene = a->scene.load();
        if (!scene) return fail(scene.message());
        printSceneNotes(*scene);
        auto cityArg = a->city.settings();
        if (!cityArg) return fail(cityArg.message());
        const std::optional<city::CitySettings> citySettings = *cityArg;
        std::filesystem::path cityTree;
        if (citySettings) {
            auto t = prepareCityTree(*scene, a->scene.cache.empty() ? defaultCacheDir() : std::filesystem::path(a->scene.cache),
                                     a->city.tree);
            if (!t) return fail(t.message());
            cityTree = *t;
        }
        LiveScene live;
        live.scene = &*scene;
        live.cache = a->scene.cache.empty() ? defaultCacheDir() : std::filesystem::path(a->scene.cache);
        auto pyr = preparePyramids(*scene, live.cache);
        if (!pyr) return fail(pyr.message());
        live.pyramids = std::move(*pyr);
        auto probe = SeasonCoverageProbe::open(live.pyramids);
        if (!probe) return fail(probe.message());
        live.coverage = std::move(*probe);
        auto elev = prepareElevation(*scene, live.cache);
        if (!elev) return fail(elev.message());
        live.elevation = std::move(*elev);

        Camera start = overviewCamera(*scene, double(size->first) / double(size->second));
        if (!a->camera.empty()) {
            auto c = parseCamera(a->camera);
            if (!c) return fail("--camera: " + c.message());
            start = c->resolve([&](double x, double y) { return scene->terrainHeight(x, y); });
        }

        auto ctx = gl::createWindowContext(size->first, size->second, "seasonview", true);
        if (!ctx) return fail(ctx.message());
        if (shotSize)
            if (auto st = gl::checkFramebufferSize((*ctx)->info(), shotSize->first, shotSize->second,
                                                   "--screenshot-size");
                !st)
                return fail(st.message());
        // The scene's GL objects die before the context, whichever way this returns.
        struct ReleaseLive {
            LiveScene& live;
            ~ReleaseLive() { live = LiveScene{}; }
        } releaseLive{live};
        auto* window = static_cast<GLFWwindow*>((*ctx)->nativeWindow());
        WindowInput input;
        glfwSetWindowUserPointer(window, &input);
        glfwSetCursorPosCallback(window, onCursor);
        glfwSetMouseButtonCallback(window, onButton);
        glfwSetScrollCallback(window, onScroll);
        glfwSetKeyCallback(window, onKey);
        glfwSwapInterval(scripted ? 0 : 1);

        // GL objects die before the context (and ImGui before both).
        int result = 0;
        {
            ClipmapOptions co;
            co.size = a->clipSize;
            auto clip = ClipmapGL::create(live.pyramids, co);
            if (!clip) return fail(clip.message());
            live.clip = std::move(*clip);
            GeometryClipmapOptions go;
            go.n = a->gridSize;
            auto terrain = ClipmapTerrainRendererGL::create(*scene, *live.clip, live.elevation ? &*live.elevation : nullptr, go);
            if (!terrain) return fail(terrain.message());
            live.terrain = std::move(*terrain);
            if (citySettings) {
                auto c = city::CityRendererGL::create(*scene, cityTree.string(), *citySettings);
                if (!c) return fail(c.message());
                live.city = std::move(*c);
            }

            IMGUI_CHECKVERSION();
            ImGui::CreateContext();
            ImGui::GetIO().IniFilename = nullptr; // no imgui.ini next to the user's files
            ImGui_ImplGlfw_InitForOpenGL(window, true);
            ImGui_ImplOpenGL3_Init("#version 450");
            struct ImGuiRelease {
                ~ImGuiRelease() {
                    ImGui_ImplOpenGL3_Shutdown();
                    ImGui_ImplGlfw_Shutdown();
                    ImGui::DestroyContext();
                }
            } imguiRelease;

            const GroundHeightFn ground = [&](double x, double y) { return scene->terrainHeight(x, y); };
            CameraNavigator nav(start, ground);
            glm::ivec2 viewport(size->first, size->second);
            const NavMode mode = startMode ? *startMode : (start.pitchDeg <= -75.0 ? NavMode::Map : NavMode::Fly);
            nav.setMode(mode, viewport);
            nav.jumpTo(nav.target());
            if (mode == NavMode::Orbit) nav.setMode(mode, viewport);

            Recorder rec;
            rec.file = a->record;
            rec.on = !a->record.empty();
            // With a fixed clock the keyframes come every whole number of frames nearest 0.25 s, so their times
            // are uniform and `bench` with one frame per keyframe replays exactly these poses.
            const int recordFrames = fixedDt > 0.0 ? std::max(1, int(std::lround(rec.step / fixedDt))) : 0;
            rec.frameStep = recordFrames;
            std::unique_ptr<gl::RenderTarget> target, scratch;
            double t = 0.0, prevT = -1.0, frameMsAvg = 0.0, coverage = std::nan("");
            bool swipeDrag = false;
            int frame = 0, shotIndex = 0, windowShotIndex = 0, screenshotCount = 0;
            std::string status;
            auto last = std::chrono::steady_clock::now();
            const ImageryView seasonViews[2] = {ImageryView::LeafOn, ImageryView::LeafOff};

            auto saveScreenshot = [&](const Camera& cam, const std::filesystem::path& file,
                                      std::optional<std::pair<int, int>> at) -> Status {
                if (at) {
                    gl::RenderTarget big(at->first, at->second);
                    live.draw(cam, s, big, true);
                    return writeRgb(big, file);
                }
                live.draw(cam, s, *target, true);
                return writeRgb(*target, file);
            };

            while (true) {
                if (glfwWindowShouldClose(window)) break;
                glfwPollEvents();
                const auto now = std::chrono::steady_clock::now();
                const double realDt = std::chrono::duration<double>(now - last).count();
                last = now;
                const double dt = frame == 0 ? 0.0 : (fixedDt > 0.0 ? fixedDt : std::min(realDt, 0.25));
                t += dt;
                if (a->quitAt >= 0.0 && t > a->quitAt + 1e-9) break;
                int fw = 0, fh = 0;
                glfwGetFramebufferSize(window, &fw, &fh);
                if (fw <= 0 || fh <= 0) continue; // minimised
                viewport = {fw, fh};
                if (!target || target->width() != fw || target->height() != fh) {
                    target = std::make_unique<gl::RenderTarget>(fw, fh);
                    scratch = std::make_unique<gl::RenderTarget>(fw, fh);
                }

                // Input: the window's and the script's, through the same handling.
                NavInput in;
                in.dt = dt;
                in.cursor = input.cursor;
                std::vector<int> pressed = std::move(input.pressedKeys);
                input.pressedKeys.clear();
                std::set<int> held = input.held;
                glm::dvec2 drag = input.drag;
                int dragButton = input.buttons[0] ? 0 : (input.buttons[1] ? 1 : -1);
                bool dragStarted[2] = {input.pressedButton[0], input.pressedButton[1]};
                glm::dvec2 dragStart[2] = {input.pressedAt[0], input.pressedAt[1]};
                double wheel = input.wheel;
                input.drag = {0.0, 0.0};
                input.wheel = 0.0;
                input.pressedButton[0] = input.pressedButton[1] = false;
                if (!script.empty()) {
                    const ScriptFrame sf = scriptFrame(script, prevT, t);
                    for (const std::string& k : sf.pressed) pressed.push_back(*keyCode(k));
                    for (const std::string& k : sf.held) held.insert(*keyCode(k));
                    if (sf.cursorSet) in.cursor = sf.cursor;
                    if (sf.dragButton >= 0) {
                        drag += sf.drag;
                        dragButton = sf.dragButton;
                        if (sf.dragStarted) {
                            dragStarted[sf.dragButton] = true;
                            dragStart[sf.dragButton] = sf.dragStart;
                        }
                    }
                    wheel += sf.wheel;
                    for (const auto& [name, value] : sf.settings) {
                        std::string err;
                        if (name == "mode") {
                            const std::string m = value.is_string() ? value.get<std::string>() : "";
                            if (m == "map") nav.setMode(NavMode::Map, viewport);
                            else if (m == "fly") nav.setMode(NavMode::Fly, viewport);
                            else if (m == "orbit") nav.setMode(NavMode::Orbit, viewport);
                            else err = "mode must be map, fly or orbit";
                        } else
                            applySetting(s, name, value, err);
                        if (!err.empty()) {
                            result = fail(a->script + ": set " + name + ": " + err);
                            break;
                        }
                    }
                    if (result != 0) break;
                }
                prevT = t;

                // Keys.
                for (int key : pressed) {
                    if (key >= GLFW_KEY_1 && key <= GLFW_KEY_9) s.view = parseImageryView(kViewKeys[key - GLFW_KEY_1]).value();
                    else if (key == GLFW_KEY_TAB) s.view = s.view == ImageryView::LeafOn ? seasonViews[1] : seasonViews[0];
                    else if (key == GLFW_KEY_C) s.layers = s.layers > 0 ? 0 : 16;
                    else if (key == GLFW_KEY_T) s.trunks = !s.trunks;
                    else if (key == GLFW_KEY_B) s.city = !s.city;
                    else if (key == GLFW_KEY_M) nav.setMode(NavMode::Map, viewport);
                    else if (key == GLFW_KEY_F) nav.setMode(NavMode::Fly, viewport);
                    else if (key == GLFW_KEY_O) {
                        const auto p = pickGround(nav.camera(), in.cursor, viewport, ground);
                        nav.setMode(NavMode::Orbit, viewport, p);
                    } else if (key == GLFW_KEY_H) s.panel = !s.panel;
                    else if (key == GLFW_KEY_K) {
                        bookmarks->cameras.push_back(nav.camera());
                        if (auto st = saveBookmarks(*bookmarks); !st) status = st.message();
                        else status = "bookmark " + std::to_string(bookmarks->cameras.size()) + " added";
                    } else if (key == GLFW_KEY_J && !bookmarks->cameras.empty()) {
                        nav.jumpTo(bookmarks->cameras[bookmarks->next++ % bookmarks->cameras.size()]);
                    } else if (key == GLFW_KEY_R) {
                        if (rec.on) {
                            rec.on = false;
                            if (auto st = rec.save(); !st) status = st.message();
                            else status = "recorded " + std::to_string(rec.keys.size()) + " keyframes";
                        } else if (!rec.file.empty()) {
                            rec = Recorder{rec.file, true};
                            rec.start = t;
                            rec.frameStep = recordFrames;
                        } else
                            status = "give --record FILE to record the flight";
                    } else if (key == GLFW_KEY_P) {
                        const std::filesystem::path file =
                            std::filesystem::path(a->screenshotDir) / ("screenshot-" + std::to_string(++screenshotCount) + ".png");
                        if (auto st = saveScreenshot(nav.camera(), file, shotSize); !st) status = st.message();
                        else status = "saved " + file.string();
                    } else if (key == GLFW_KEY_ESCAPE)
                        glfwSetWindowShouldClose(window, GLFW_TRUE);
                }
                in.forward = held.count(GLFW_KEY_W) > 0;
                in.back = held.count(GLFW_KEY_S) > 0;
                in.left = held.count(GLFW_KEY_A) > 0;
                in.right = held.count(GLFW_KEY_D) > 0;
                in.up = held.count(GLFW_KEY_E) > 0;
                in.down = held.count(GLFW_KEY_Q) > 0;
                in.fast = held.count(GLFW_KEY_LEFT_SHIFT) > 0 || held.count(GLFW_KEY_RIGHT_SHIFT) > 0;
                in.wheel = wheel;
                // The swipe bar: a drag starting on it moves it instead of the camera.
                if (dragStarted[0] && s.view == ImageryView::Swipe)
                    swipeDrag = std::abs(dragStart[0].x - double(s.swipe) * double(viewport.x)) <= 8.0;
                if (dragButton != 0) swipeDrag = false;
                if (swipeDrag) s.swipe = float(std::clamp(in.cursor.x / double(viewport.x), 0.0, 1.0));
                else if (dragButton == 0) in.drag = drag;
                // Right button: orbit around the ground point clicked.
                if (dragStarted[1]) {
                    if (const auto p = pickGround(nav.camera(), dragStart[1], viewport, ground))
                        nav.setMode(NavMode::Orbit, viewport, p);
                }
                if (dragButton == 1) in.drag = drag;
                const Camera cam = nav.update(in, viewport);
                rec.add(t, cam);

                // Draw.
                if (s.view == ImageryView::Canopy)
                    if (auto st = live.ensureCanopy(s); !st) {
                        result = fail(st.message());
                        break;
                    }
                const auto f0 = std::chrono::steady_clock::now();
                while (shotIndex < int(shots.size()) && shots[size_t(shotIndex)].t <= t + 1e-9) {
                    if (auto st = saveScreenshot(cam, shots[size_t(shotIndex)].file, std::nullopt); !st) {
                        result = fail(st.message());
                        break;
                    }
                    std::printf("saved %s at %.3f s\n", shots[size_t(shotIndex)].file.c_str(), t);
                    ++shotIndex;
                }
                if (result != 0) break;
                const GeometryFrameStats drawn = live.draw(cam, s, *target, false);
                if (s.coverageEvery > 0 && frame % s.coverageEvery == 0)
                    coverage = live.terrain->measureLevels(cam, *scratch).coverage;
                target->blitToDefault(fw, fh);
                glFinish();
                const double frameMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - f0).count();
                frameMsAvg = frame == 0 ? frameMs : 0.9 * frameMsAvg + 0.1 * frameMs;

                // Panel and HUD.
                ImGui_ImplOpenGL3_NewFrame();
                ImGui_ImplGlfw_NewFrame();
                ImGui::NewFrame();
                if (s.panel) {
                    ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_FirstUseEver);
                    ImGui::SetNextWindowSize(ImVec2(420, 0), ImGuiCond_FirstUseEver);
                    ImGui::Begin("seasonview");
                    int v = int(s.view);
                    ImGui::TextUnformatted("Season");
                    ImGui::RadioButton("leaf-on", &v, int(ImageryView::LeafOn));
                    ImGui::SameLine();
                    ImGui::RadioButton("leaf-off", &v, int(ImageryView::LeafOff));
                    ImGui::SameLine();
                    ImGui::RadioButton("blend", &v, int(ImageryView::Blend));
                    ImGui::SameLine();
                    ImGui::RadioButton("swipe", &v, int(ImageryView::Swipe));
                    ImGui::SliderFloat("blend", &s.blend, 0.0f, 1.0f);
                    ImGui::SliderFloat("swipe", &s.swipe, 0.0f, 1.0f);
                    ImGui::TextUnformatted("Views");
                    ImGui::RadioButton("canopy", &v, int(ImageryView::Canopy));
                    ImGui::SameLine();
                    ImGui::RadioButton("lod", &v, int(ImageryView::Lod));
                    ImGui::SameLine();
                    ImGui::RadioButton("levels", &v, int(ImageryView::Levels));
                    ImGui::RadioButton("wireframe", &v, int(ImageryView::Wireframe));
                    ImGui::SameLine();
                    ImGui::RadioButton("relief", &v, int(ImageryView::Relief));
                    s.view = ImageryView(v);
                    ImGui::SliderFloat("shading", &s.shading, 0.0f, 1.0f);
                    bool layersOn = s.layers > 0;
                    int n = std::max(s.layers, 1);
                    if (ImGui::Checkbox("canopy layers", &layersOn)) s.layers = layersOn ? 16 : 0;
                    if (layersOn && ImGui::SliderInt("layers", &n, 1, 32)) s.layers = n;
                    ImGui::Checkbox("trunks", &s.trunks);
                    ImGui::Checkbox("march the layers per pixel", &s.marchLayers);
                    if (live.city) {
                        ImGui::Checkbox("city (B)", &s.city);
                        ImGui::SliderFloat("city pixels per texel", &s.cityTpp, 0.25f, 8.0f, "%.2f",
                                           ImGuiSliderFlags_Logarithmic);
                    }
                    int method = int(s.params.method);
                    ImGui::Combo("method", &method, "pixel\0neighborhood\0equalized\0default\0");
                    s.params.method = SegmentationMethod(method);
                    int k = s.params.k;
                    if (ImGui::SliderInt("k", &k, 1, kSegMaxK)) s.params.k = k % 2 == 1 ? k : k + 1;
                    int centers = int(s.centers);
                    ImGui::Combo("centres", &centers, "concentric\0offset\0footprint\0");
                    s.centers = CenterPlacement(centers);
                    int m = int(nav.mode());
                    ImGui::TextUnformatted("Navigation");
                    ImGui::RadioButton("map", &m, int(NavMode::Map));
                    ImGui::SameLine();
                    ImGui::RadioButton("fly", &m, int(NavMode::Fly));
                    ImGui::SameLine();
                    ImGui::RadioButton("orbit", &m, int(NavMode::Orbit));
                    if (m != int(nav.mode())) nav.setMode(NavMode(m), viewport);
                    if (ImGui::Button("screenshot (P)")) input.pressedKeys.push_back(GLFW_KEY_P);
                    ImGui::SameLine();
                    if (ImGui::Button("bookmark (K)")) input.pressedKeys.push_back(GLFW_KEY_K);
                    ImGui::SameLine();
                    if (ImGui::Button(rec.on ? "stop recording (R)" : "record (R)")) input.pressedKeys.push_back(GLFW_KEY_R);
                    for (size_t i = 0; i < bookmarks->cameras.size(); ++i) {
                        ImGui::PushID(int(i));
                        if (ImGui::SmallButton(("go " + std::to_string(i + 1)).c_str())) nav.jumpTo(bookmarks->cameras[i]);
                        ImGui::PopID();
                        if (i % 6 != 5 && i + 1 < bookmarks->cameras.size()) ImGui::SameLine();
                    }
                    ImGui::Separator();
                    // HUD.
                    const glm::dvec2 local(cam.position.x, cam.position.y);
                    const Crs& crs = scene->grid.georef.crs;
                    const glm::dvec2 inCrs = scene->frame.fromLocal(crs, local);
                    const glm::dvec2 lonLat = crs.isGeographic() ? inCrs : convert(crs, Crs::geographic(), inCrs);
                    ImGui::Text("frame %.1f ms (%.1f fps)", frameMsAvg, frameMsAvg > 0 ? 1000.0 / frameMsAvg : 0.0);
                    ImGui::Text("%lld triangles, %d draw calls", (long long)drawn.triangles, drawn.drawCalls);
                    ImGui::Text("coverage %.3f", coverage);
                    if (live.city && s.city)
                        ImGui::Text("city: %d atlases (%d hidden), %d binds, %d calls, %zu blocks %.1f MB, queue %zu",
                                    live.cityStats.atlasNodes, live.cityStats.occludedNodes,
                                    live.cityStats.textureBinds, live.cityStats.drawCalls,
                                    live.cityStats.blocksResident, double(live.cityStats.residentBytes) / 1048576.0,
                                    live.cityStats.loaderQueue);
                    ImGui::Text("texels uploaded %lld (total %.1f M)", (long long)live.lastLoad.texelsUploaded,
                                double(live.texelsTotal) / 1e6);
                    ImGui::Text("resident %.1f MB, loader queue %d blocks", double(live.residentBytes()) / 1048576.0,
                                live.lastLoad.blocksMissing);
                    ImGui::Text("camera %.1f, %.1f, %.1f m, yaw %.1f, pitch %.1f (%s)", cam.position.x, cam.position.y,
                                cam.position.z, cam.yawDeg, cam.pitchDeg, navModeName(nav.mode()));
                    ImGui::Text("%.2f m above ground", cam.position.z - ground(cam.position.x, cam.position.y));
                    ImGui::Text("%s: %.2f, %.2f", crs.name().c_str(), inCrs.x, inCrs.y);
                    ImGui::Text("lat %.6f, lon %.6f", lonLat.y, lonLat.x);
                    {
                        // The seasons that have data at the ground point under the cursor.
                        const auto hit = pickGround(cam, input.cursor, viewport, ground);
                        const auto c = hit ? live.coverage->at(scene->localToImagePixel(glm::dvec2(*hit)))
                                           : std::optional<SeasonCoverage>();
                        ImGui::Text("under the cursor: %s", c ? c->describe() : "outside the imagery");
                    }
                    if (!status.empty()) ImGui::TextWrapped("%s", status.c_str());
                    ImGui::End();
                }
                ImGui::Render();
                glBindFramebuffer(GL_FRAMEBUFFER, 0);
                glViewport(0, 0, fw, fh);
                ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
                while (windowShotIndex < int(windowShots.size()) && windowShots[size_t(windowShotIndex)].t <= t + 1e-9) {
                    // The back buffer as it is about to be shown: the view, the panel and the HUD.
                    std::vector<std::uint8_t> rgb(size_t(fw) * size_t(fh) * 3);
                    glPixelStorei(GL_PACK_ALIGNMENT, 1);
                    glReadBuffer(GL_BACK);
                    glReadPixels(0, 0, fw, fh, GL_RGB, GL_UNSIGNED_BYTE, rgb.data());
                    std::vector<std::uint8_t> top(rgb.size());
                    for (int y = 0; y < fh; ++y)
                        std::copy_n(&rgb[size_t(fh - 1 - y) * size_t(fw) * 3], size_t(fw) * 3, &top[size_t(y) * size_t(fw) * 3]);
                    const std::filesystem::path& file = windowShots[size_t(windowShotIndex)].file;
                    if (auto st = writeImageAtomic(file, top.data(), fw, fh, 3); !st) {
                        result = fail(st.message());
                        break;
                    }
                    std::printf("saved %s (window) at %.3f s\n", file.c_str(), t);
                    ++windowShotIndex;
                }
                if (result != 0) break;
                glfwSwapBuffers(window);
                ++frame;
                if (std::string e = gl::drainErrors(); !e.empty()) {
                    result = fail("OpenGL error: " + e);
                    break;
                }
            }
            if (auto st = rec.save(); !st && result == 0) result = fail(st.message());
            if (result == 0 && windowShotIndex < int(windowShots.size()))
                result = fail("--window-screenshot-at " + std::to_string(windowShots[size_t(windowShotIndex)].t) +
                              ": the viewer ended before that time (see --quit-at)");
            if (result == 0 && shotIndex < int(shots.size()))
                result = fail("--screenshot-at " + std::to_string(shots[size_t(shotIndex)].t) +
                              ": the viewer ended before that time (see --quit-at)");
        }
        return result;
    };
}

} // namespace seasonview::app
