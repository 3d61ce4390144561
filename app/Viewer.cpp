#include "Viewer.h"

#include "AtomicFile.h"
#include "CityJob.h"
#include "RenderJob.h"
#include "ViewerInput.h"
#include "gl/GlContext.h"
#include "gl/GlDebug.h"

#include <epoxy/gl.h>
#ifndef GLFW_INCLUDE_NONE
#define GLFW_INCLUDE_NONE
#endif
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>

namespace seasonview::app {

namespace {

int fail(const std::string& m) {
    std::fprintf(stderr, "seasonview view: %s\n", m.c_str());
    return 1;
}

// Keys 1..9.
const char* kViewKeys[] = {"leafon", "leafoff", "blend", "swipe", "canopy", "lod", "levels", "wireframe", "relief"};

// The viewer's frame loop over a window whose GL objects (`live`) exist: input, navigation, drawing, the panel and
// HUD, screenshots. One instance per run; ImGui's context lives as long as it does.
class Viewer {
public:
    Viewer(const Scene& scene, LiveScene& live, ViewerOptions& o, GLFWwindow* window)
        : m_scene(scene), m_live(live), m_o(o), m_s(o.settings), m_window(window),
          m_ground([&scene](double x, double y) { return scene.terrainHeight(x, y); }), m_nav(o.start, m_ground),
          m_viewport(o.size.first, o.size.second) {
        attachWindowInput(window, m_input);
        glfwSwapInterval(o.scripted ? 0 : 1);
        const NavMode mode = o.mode ? *o.mode : (o.start.pitchDeg <= -75.0 ? NavMode::Map : NavMode::Fly);
        m_nav.setMode(mode, m_viewport);
        m_nav.jumpTo(m_nav.target());
        if (mode == NavMode::Orbit) m_nav.setMode(mode, m_viewport);
        m_rec.file = o.record;
        m_rec.on = !o.record.empty();
        // With a fixed clock the keyframes come every whole number of frames nearest 0.25 s, so their times are
        // uniform and `bench` with one frame per keyframe replays exactly these poses.
        m_recordFrames = o.fixedDt > 0.0 ? std::max(1, int(std::lround(m_rec.step / o.fixedDt))) : 0;
        m_rec.frameStep = m_recordFrames;
        IMGUI_CHECKVERSION();
        ImGui::CreateContext();
        ImGui::GetIO().IniFilename = nullptr; // no imgui.ini next to the user's files
        ImGui_ImplGlfw_InitForOpenGL(window, true);
        ImGui_ImplOpenGL3_Init("#version 450");
    }
    ~Viewer() {
        ImGui_ImplOpenGL3_Shutdown();
        ImGui_ImplGlfw_Shutdown();
        ImGui::DestroyContext();
    }
    Viewer(const Viewer&) = delete;
    Viewer& operator=(const Viewer&) = delete;

    // Runs until the window closes, Escape, --quit-at or an error (returned).
    Status run();

private:
    Status frame(int fw, int fh, double dt);
    Status applyScriptSettings(const FrameInput& in);
    void handleKeys(const std::vector<int>& pressed, glm::dvec2 cursor);
    NavInput navigationInput(const FrameInput& in, double dt);
    Status saveScreenshot(const Camera& cam, const std::filesystem::path& file, std::optional<std::pair<int, int>> at);
    Status timedScreenshots(const Camera& cam);
    Status windowScreenshots(int fw, int fh);
    void panel(const Camera& cam, const GeometryFrameStats& drawn);
    void hud(const Camera& cam, const GeometryFrameStats& drawn);
    Status endOfRun() const;

    const Scene& m_scene;
    LiveScene& m_live;
    ViewerOptions& m_o;
    ViewerSettings m_s;
    GLFWwindow* m_window;
    WindowInput m_input;
    GroundHeightFn m_ground;
    CameraNavigator m_nav;
    glm::ivec2 m_viewport;
    Recorder m_rec;
    int m_recordFrames = 0;
    std::unique_ptr<gl::RenderTarget> m_target, m_scratch;
    double m_t = 0.0, m_prevT = -1.0, m_frameMsAvg = 0.0, m_coverage = std::nan("");
    bool m_swipeDrag = false;
    int m_frame = 0, m_shotIndex = 0, m_windowShotIndex = 0, m_screenshotCount = 0;
    std::string m_status; // the last action's message (panel)
};

Status Viewer::run() {
    auto last = std::chrono::steady_clock::now();
    Status result = Ok{};
    while (!glfwWindowShouldClose(m_window)) {
        glfwPollEvents();
        const auto now = std::chrono::steady_clock::now();
        const double realDt = std::chrono::duration<double>(now - last).count();
        last = now;
        const double dt = m_frame == 0 ? 0.0 : (m_o.fixedDt > 0.0 ? m_o.fixedDt : std::min(realDt, 0.25));
        m_t += dt;
        if (m_o.quitAt >= 0.0 && m_t > m_o.quitAt + 1e-9) break;
        int fw = 0, fh = 0;
        glfwGetFramebufferSize(m_window, &fw, &fh);
        if (fw <= 0 || fh <= 0) continue; // minimised
        if (result = frame(fw, fh, dt); !result) break;
    }
    if (auto st = m_rec.save(); !st && result) result = st;
    if (result) result = endOfRun();
    return result;
}

// Screenshots asked for at times the run never reached are an error.
Status Viewer::endOfRun() const {
    if (m_windowShotIndex < int(m_o.windowShots.size()))
        return Error{"--window-screenshot-at " + std::to_string(m_o.windowShots[size_t(m_windowShotIndex)].t) +
                     ": the viewer ended before that time (see --quit-at)"};
    if (m_shotIndex < int(m_o.shots.size()))
        return Error{"--screenshot-at " + std::to_string(m_o.shots[size_t(m_shotIndex)].t) +
                     ": the viewer ended before that time (see --quit-at)"};
    return Ok{};
}

Status Viewer::frame(int fw, int fh, double dt) {
    m_viewport = {fw, fh};
    if (!m_target || m_target->width() != fw || m_target->height() != fh) {
        m_target = std::make_unique<gl::RenderTarget>(fw, fh);
        m_scratch = std::make_unique<gl::RenderTarget>(fw, fh);
    }
    // Input: the window's and the script's, through the same handling.
    const FrameInput in = takeFrameInput(m_input, m_o.script, m_prevT, m_t);
    if (auto st = applyScriptSettings(in); !st) return st;
    m_prevT = m_t;
    handleKeys(in.pressed, in.cursor);
    const Camera cam = m_nav.update(navigationInput(in, dt), m_viewport);
    m_rec.add(m_t, cam);

    // Draw.
    if (m_s.imagery.view == ImageryView::Canopy)
        if (auto st = m_live.ensureCanopy(m_s); !st) return st;
    const auto f0 = std::chrono::steady_clock::now();
    if (auto st = timedScreenshots(cam); !st) return st;
    const GeometryFrameStats drawn = m_live.draw(cam, m_s, *m_target, false);
    if (m_s.coverageEvery > 0 && m_frame % m_s.coverageEvery == 0)
        m_coverage = m_live.terrain->measureLevels(cam, *m_scratch).coverage;
    m_target->blitToDefault(fw, fh);
    glFinish();
    const double frameMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - f0).count();
    m_frameMsAvg = m_frame == 0 ? frameMs : 0.9 * m_frameMsAvg + 0.1 * frameMs;

    // Panel and HUD.
    ImGui_ImplOpenGL3_NewFrame();
    ImGui_ImplGlfw_NewFrame();
    ImGui::NewFrame();
    if (m_s.panel) panel(cam, drawn);
    ImGui::Render();
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glViewport(0, 0, fw, fh);
    ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
    if (auto st = windowScreenshots(fw, fh); !st) return st;
    glfwSwapBuffers(m_window);
    ++m_frame;
    if (std::string e = gl::drainErrors(); !e.empty()) return Error{"OpenGL error: " + e};
    return Ok{};
}

Status Viewer::applyScriptSettings(const FrameInput& in) {
    for (const auto& [name, value] : in.settings) {
        std::string err;
        if (name == "mode") {
            const std::string m = value.is_string() ? value.get<std::string>() : "";
            if (m == "map") m_nav.setMode(NavMode::Map, m_viewport);
            else if (m == "fly") m_nav.setMode(NavMode::Fly, m_viewport);
            else if (m == "orbit") m_nav.setMode(NavMode::Orbit, m_viewport);
            else err = "mode must be map, fly or orbit";
        } else
            applySetting(m_s, name, value, err);
        if (!err.empty()) return Error{m_o.scriptName + ": set " + name + ": " + err};
    }
    return Ok{};
}

void Viewer::handleKeys(const std::vector<int>& pressed, glm::dvec2 cursor) {
    for (int key : pressed) {
        if (key >= GLFW_KEY_1 && key <= GLFW_KEY_9) m_s.imagery.view = parseImageryView(kViewKeys[key - GLFW_KEY_1]).value();
        else if (key == GLFW_KEY_TAB)
            m_s.imagery.view = m_s.imagery.view == ImageryView::LeafOn ? ImageryView::LeafOff : ImageryView::LeafOn;
        else if (key == GLFW_KEY_C) m_s.layers = m_s.layers > 0 ? 0 : 16;
        else if (key == GLFW_KEY_T) m_s.trunks = !m_s.trunks;
        else if (key == GLFW_KEY_B) m_s.city = !m_s.city;
        else if (key == GLFW_KEY_G) m_s.cityBlockMaps = !m_s.cityBlockMaps;
        else if (key == GLFW_KEY_M) m_nav.setMode(NavMode::Map, m_viewport);
        else if (key == GLFW_KEY_F) m_nav.setMode(NavMode::Fly, m_viewport);
        else if (key == GLFW_KEY_O) {
            const auto p = pickGround(m_nav.camera(), cursor, m_viewport, m_ground);
            m_nav.setMode(NavMode::Orbit, m_viewport, p);
        } else if (key == GLFW_KEY_H) m_s.panel = !m_s.panel;
        else if (key == GLFW_KEY_K) {
            m_o.bookmarks.cameras.push_back(m_nav.camera());
            if (auto st = saveBookmarks(m_o.bookmarks); !st) m_status = st.message();
            else m_status = "bookmark " + std::to_string(m_o.bookmarks.cameras.size()) + " added";
        } else if (key == GLFW_KEY_J && !m_o.bookmarks.cameras.empty()) {
            m_nav.jumpTo(m_o.bookmarks.cameras[m_o.bookmarks.next++ % m_o.bookmarks.cameras.size()]);
        } else if (key == GLFW_KEY_R) {
            if (m_rec.on) {
                m_rec.on = false;
                if (auto st = m_rec.save(); !st) m_status = st.message();
                else m_status = "recorded " + std::to_string(m_rec.keys.size()) + " keyframes";
            } else if (!m_rec.file.empty()) {
                m_rec = Recorder{m_rec.file, true};
                m_rec.start = m_t;
                m_rec.frameStep = m_recordFrames;
            } else
                m_status = "give --record FILE to record the flight";
        } else if (key == GLFW_KEY_P) {
            const std::filesystem::path file =
                m_o.screenshotDir / ("screenshot-" + std::to_string(++m_screenshotCount) + ".png");
            if (auto st = saveScreenshot(m_nav.camera(), file, m_o.shotSize); !st) m_status = st.message();
            else m_status = "saved " + file.string();
        } else if (key == GLFW_KEY_ESCAPE)
            glfwSetWindowShouldClose(m_window, GLFW_TRUE);
    }
}

NavInput Viewer::navigationInput(const FrameInput& f, double dt) {
    NavInput in;
    in.dt = dt;
    in.cursor = f.cursor;
    auto held = [&](int key) { return f.held.count(key) > 0; };
    in.forward = held(GLFW_KEY_W);
    in.back = held(GLFW_KEY_S);
    in.left = held(GLFW_KEY_A);
    in.right = held(GLFW_KEY_D);
    in.up = held(GLFW_KEY_E);
    in.down = held(GLFW_KEY_Q);
    in.fast = held(GLFW_KEY_LEFT_SHIFT) || held(GLFW_KEY_RIGHT_SHIFT);
    in.wheel = f.wheel;
    // The swipe bar: a drag starting on it moves it instead of the camera.
    if (f.dragStarted[0] && m_s.imagery.view == ImageryView::Swipe)
        m_swipeDrag = std::abs(f.dragStart[0].x - double(m_s.imagery.swipe) * double(m_viewport.x)) <= 8.0;
    if (f.dragButton != 0) m_swipeDrag = false;
    if (m_swipeDrag) m_s.imagery.swipe = float(std::clamp(in.cursor.x / double(m_viewport.x), 0.0, 1.0));
    else if (f.dragButton == 0) in.drag = f.drag;
    // Right button: orbit around the ground point clicked.
    if (f.dragStarted[1])
        if (const auto p = pickGround(m_nav.camera(), f.dragStart[1], m_viewport, m_ground))
            m_nav.setMode(NavMode::Orbit, m_viewport, p);
    if (f.dragButton == 1) in.drag = f.drag;
    return in;
}

Status Viewer::saveScreenshot(const Camera& cam, const std::filesystem::path& file,
                              std::optional<std::pair<int, int>> at) {
    if (at) {
        gl::RenderTarget big(at->first, at->second);
        m_live.draw(cam, m_s, big, true);
        return writeRgb(big, file);
    }
    m_live.draw(cam, m_s, *m_target, true);
    return writeRgb(*m_target, file);
}

// --screenshot-at: the view, every texel it needs resident, at the first frame at or after each time.
Status Viewer::timedScreenshots(const Camera& cam) {
    while (m_shotIndex < int(m_o.shots.size()) && m_o.shots[size_t(m_shotIndex)].t <= m_t + 1e-9) {
        const TimedScreenshot& shot = m_o.shots[size_t(m_shotIndex)];
        if (auto st = saveScreenshot(cam, shot.file, std::nullopt); !st) return st;
        std::printf("saved %s at %.3f s\n", shot.file.c_str(), m_t);
        ++m_shotIndex;
    }
    return Ok{};
}

// --window-screenshot-at: the back buffer as it is about to be shown (the view, the panel and the HUD).
Status Viewer::windowScreenshots(int fw, int fh) {
    while (m_windowShotIndex < int(m_o.windowShots.size()) && m_o.windowShots[size_t(m_windowShotIndex)].t <= m_t + 1e-9) {
        std::vector<std::uint8_t> rgb(size_t(fw) * size_t(fh) * 3);
        glPixelStorei(GL_PACK_ALIGNMENT, 1);
        glReadBuffer(GL_BACK);
        glReadPixels(0, 0, fw, fh, GL_RGB, GL_UNSIGNED_BYTE, rgb.data());
        std::vector<std::uint8_t> top(rgb.size());
        for (int y = 0; y < fh; ++y)
            std::copy_n(&rgb[size_t(fh - 1 - y) * size_t(fw) * 3], size_t(fw) * 3, &top[size_t(y) * size_t(fw) * 3]);
        const std::filesystem::path& file = m_o.windowShots[size_t(m_windowShotIndex)].file;
        if (auto st = writeImageAtomic(file, top.data(), fw, fh, 3); !st) return st;
        std::printf("saved %s (window) at %.3f s\n", file.c_str(), m_t);
        ++m_windowShotIndex;
    }
    return Ok{};
}

// The settings panel: seasons and views, canopy, city, segmentation, centres, navigation, actions; the HUD below.
void Viewer::panel(const Camera& cam, const GeometryFrameStats& drawn) {
    ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_FirstUseEver);
    ImGui::SetNextWindowSize(ImVec2(420, 0), ImGuiCond_FirstUseEver);
    ImGui::Begin("seasonview");
    int v = int(m_s.imagery.view);
    ImGui::TextUnformatted("Season");
    ImGui::RadioButton("leaf-on", &v, int(ImageryView::LeafOn));
    ImGui::SameLine();
    ImGui::RadioButton("leaf-off", &v, int(ImageryView::LeafOff));
    ImGui::SameLine();
    ImGui::RadioButton("blend", &v, int(ImageryView::Blend));
    ImGui::SameLine();
    ImGui::RadioButton("swipe", &v, int(ImageryView::Swipe));
    ImGui::SliderFloat("blend", &m_s.imagery.blend, 0.0f, 1.0f);
    ImGui::SliderFloat("swipe", &m_s.imagery.swipe, 0.0f, 1.0f);
    ImGui::TextUnformatted("Views");
    ImGui::RadioButton("canopy", &v, int(ImageryView::Canopy));
    ImGui::SameLine();
    ImGui::RadioButton("lod", &v, int(ImageryView::Lod));
    ImGui::SameLine();
    ImGui::RadioButton("levels", &v, int(ImageryView::Levels));
    ImGui::RadioButton("wireframe", &v, int(ImageryView::Wireframe));
    ImGui::SameLine();
    ImGui::RadioButton("relief", &v, int(ImageryView::Relief));
    m_s.imagery.view = ImageryView(v);
    ImGui::SliderFloat("shading", &m_s.imagery.shading, 0.0f, 1.0f);
    bool layersOn = m_s.layers > 0;
    int n = std::max(m_s.layers, 1);
    if (ImGui::Checkbox("canopy layers", &layersOn)) m_s.layers = layersOn ? 16 : 0;
    if (layersOn && ImGui::SliderInt("layers", &n, 1, 32)) m_s.layers = n;
    ImGui::Checkbox("trunks", &m_s.trunks);
    ImGui::Checkbox("march the layers per pixel", &m_s.marchLayers);
    if (m_live.city) {
        ImGui::Checkbox("city (B)", &m_s.city);
        ImGui::SliderFloat("city pixels per texel", &m_s.cityTpp, 0.25f, 8.0f, "%.2f", ImGuiSliderFlags_Logarithmic);
        if (m_live.city->hasBlockMaps()) {
            ImGui::Checkbox("BlockMaps far (G)", &m_s.cityBlockMaps);
            float e = float(m_live.city->settings().blockMapErrorPx);
            if (ImGui::SliderFloat("BlockMap error, px", &e, 0.25f, 8.0f, "%.2f", ImGuiSliderFlags_Logarithmic))
                m_live.city->settings().blockMapErrorPx = double(e);
        }
    }
    int method = int(m_s.params.method);
    ImGui::Combo("method", &method, "pixel\0neighborhood\0equalized\0default\0");
    m_s.params.method = SegmentationMethod(method);
    int k = m_s.params.k;
    if (ImGui::SliderInt("k", &k, 1, kSegMaxK)) m_s.params.k = k % 2 == 1 ? k : k + 1;
    int centers = int(m_s.centers);
    ImGui::Combo("centres", &centers, "concentric\0offset\0footprint\0");
    m_s.centers = CenterPlacement(centers);
    int m = int(m_nav.mode());
    ImGui::TextUnformatted("Navigation");
    ImGui::RadioButton("map", &m, int(NavMode::Map));
    ImGui::SameLine();
    ImGui::RadioButton("fly", &m, int(NavMode::Fly));
    ImGui::SameLine();
    ImGui::RadioButton("orbit", &m, int(NavMode::Orbit));
    if (m != int(m_nav.mode())) m_nav.setMode(NavMode(m), m_viewport);
    if (ImGui::Button("screenshot (P)")) m_input.pressedKeys.push_back(GLFW_KEY_P);
    ImGui::SameLine();
    if (ImGui::Button("bookmark (K)")) m_input.pressedKeys.push_back(GLFW_KEY_K);
    ImGui::SameLine();
    if (ImGui::Button(m_rec.on ? "stop recording (R)" : "record (R)")) m_input.pressedKeys.push_back(GLFW_KEY_R);
    for (size_t i = 0; i < m_o.bookmarks.cameras.size(); ++i) {
        ImGui::PushID(int(i));
        if (ImGui::SmallButton(("go " + std::to_string(i + 1)).c_str())) m_nav.jumpTo(m_o.bookmarks.cameras[i]);
        ImGui::PopID();
        if (i % 6 != 5 && i + 1 < m_o.bookmarks.cameras.size()) ImGui::SameLine();
    }
    ImGui::Separator();
    hud(cam, drawn);
    if (!m_status.empty()) ImGui::TextWrapped("%s", m_status.c_str());
    ImGui::End();
}

// The HUD: frame time, geometry, coverage, the city's paging, uploads and memory, where the camera is, and which
// season has data under the cursor.
void Viewer::hud(const Camera& cam, const GeometryFrameStats& drawn) {
    const glm::dvec2 local(cam.position.x, cam.position.y);
    const Crs& crs = m_scene.grid.georef.crs;
    const glm::dvec2 inCrs = m_scene.frame.fromLocal(crs, local);
    const glm::dvec2 lonLat = crs.isGeographic() ? inCrs : convert(crs, Crs::geographic(), inCrs);
    ImGui::Text("frame %.1f ms (%.1f fps)", m_frameMsAvg, m_frameMsAvg > 0 ? 1000.0 / m_frameMsAvg : 0.0);
    ImGui::Text("%lld triangles, %d draw calls", (long long)drawn.triangles, drawn.drawCalls);
    ImGui::Text("coverage %.3f", m_coverage);
    if (m_live.city && m_s.city) {
        const city::CityFrameStats& c = m_live.cityStats;
        ImGui::Text("city: %d atlases (%d hidden), %d binds, %d calls, %zu blocks %.1f MB, queue %zu", c.atlasNodes,
                    c.occludedNodes, c.textureBinds, c.drawCalls, c.blocksResident,
                    double(c.residentBytes) / 1048576.0, c.loaderQueue);
        if (m_live.city->hasBlockMaps())
            ImGui::Text("city: %d BlockMaps (%d loading), %lld triangles", c.blockMaps, c.blockMapsNotResident,
                        (long long)c.triangles);
    }
    ImGui::Text("texels uploaded %lld (total %.1f M)", (long long)m_live.lastLoad.texelsUploaded,
                double(m_live.texelsTotal) / 1e6);
    ImGui::Text("resident %.1f MB, loader queue %d blocks", double(m_live.residentBytes()) / 1048576.0,
                m_live.lastLoad.blocksMissing);
    if (m_live.clip->streaming())
        ImGui::Text("streamed: %lld tile errors%s%s", (long long)m_live.clip->streamErrors(),
                    m_live.clip->streamErrors() ? ", last: " : "", m_live.clip->lastStreamError().c_str());
    ImGui::Text("camera %.1f, %.1f, %.1f m, yaw %.1f, pitch %.1f (%s)", cam.position.x, cam.position.y, cam.position.z,
                cam.yawDeg, cam.pitchDeg, navModeName(m_nav.mode()));
    ImGui::Text("%.2f m above ground", cam.position.z - m_ground(cam.position.x, cam.position.y));
    ImGui::Text("%s: %.2f, %.2f", crs.name().c_str(), inCrs.x, inCrs.y);
    ImGui::Text("lat %.6f, lon %.6f", lonLat.y, lonLat.x);
    // The seasons that have data at the ground point under the cursor.
    const auto hit = pickGround(cam, m_input.cursor, m_viewport, m_ground);
    const auto c = hit ? m_live.coverage->at(m_scene.localToImagePixel(glm::dvec2(*hit))) : std::optional<SeasonCoverage>();
    ImGui::Text("under the cursor: %s", c ? c->describe() : "outside the imagery");
}

// The scene's pyramids, coverage probe and elevation, read before a window opens.
Status prepareLive(const Scene& scene, const ViewerOptions& o, LiveScene& live) {
    live.scene = &scene;
    live.cache = o.cache;
    auto pyr = preparePyramids(scene, live.cache);
    if (!pyr) return pyr.error();
    live.pyramids = std::move(*pyr);
    auto probe = SeasonCoverageProbe::open(live.pyramids);
    if (!probe) return probe.error();
    live.coverage = std::move(*probe);
    auto elev = prepareElevation(scene, live.cache);
    if (!elev) return elev.error();
    live.elevation = std::move(*elev);
    return Ok{};
}

// The clipmaps, terrain and city on the window's context.
Status createRenderers(const Scene& scene, const ViewerOptions& o, LiveScene& live) {
    ClipmapOptions co;
    co.size = o.clipSize;
    co.minClipLevels = o.clipLevels;
    auto clip = ClipmapGL::create(live.pyramids, co);
    if (!clip) return clip.error();
    live.clip = std::move(*clip);
    GeometryClipmapOptions go;
    go.n = o.gridSize;
    auto terrain = ClipmapTerrainRendererGL::create(scene, *live.clip, live.elevation ? &*live.elevation : nullptr, go);
    if (!terrain) return terrain.error();
    live.terrain = std::move(*terrain);
    if (o.city) {
        city::CitySettings cs = *o.city;
        if (auto st = prepareCityBlockMaps(scene, o.cityTree, o.cache, cs); !st) return st.error();
        auto c = city::CityRendererGL::create(scene, o.cityTree.string(), cs);
        if (!c) return c.error();
        live.city = std::move(*c);
    }
    return Ok{};
}

} // namespace

int runViewer(const Scene& scene, ViewerOptions options) {
    LiveScene live;
    if (auto st = prepareLive(scene, options, live); !st) return fail(st.message());
    auto ctx = gl::createWindowContext(options.size.first, options.size.second, "seasonview", true);
    if (!ctx) return fail(ctx.message());
    if (options.shotSize)
        if (auto st = gl::checkFramebufferSize((*ctx)->info(), options.shotSize->first, options.shotSize->second,
                                               "--screenshot-size");
            !st)
            return fail(st.message());
    // The scene's GL objects die before the context, whichever way this returns (and ImGui before both).
    struct ReleaseLive {
        LiveScene& live;
        ~ReleaseLive() { live = LiveScene{}; }
    } releaseLive{live};
    if (auto st = createRenderers(scene, options, live); !st) return fail(st.message());
    Viewer viewer(scene, live, options, static_cast<GLFWwindow*>((*ctx)->nativeWindow()));
    if (auto st = viewer.run(); !st) return fail(st.message());
    return 0;
}

} // namespace seasonview::app
