#include "RenderJob.h"

#include "gl/GlDebug.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>

namespace seasonview::app {

void SceneArgs::addTo(CLI::App& cmd) {
    cmd.add_option("scene", manifest, "Scene manifest (scene.json); or give --leafon/--leafoff");
    cmd.add_option("--leafon", leafon, "Leaf-on (summer) GeoTIFF, 8- or 16-bit RGB");
    cmd.add_option("--leafoff", leafoff, "Leaf-off (winter) GeoTIFF on the same grid");
    cmd.add_option("--dem", dem, "Elevation GeoTIFF (float32 or int16; geographic or UTM); flat without");
    cmd.add_option("--cache", cache, "Cache folder (default $SEASONVIEW_CACHE or ~/.cache/seasonview)");
}

Result<Scene> SceneArgs::load() const {
    SceneSources src;
    if (!manifest.empty()) {
        if (!leafon.empty() || !leafoff.empty() || !dem.empty())
            return Error{"scene: give either a manifest or --leafon/--leafoff/--dem, not both"};
        auto parsed = parseManifest(manifest);
        if (!parsed) return parsed.error();
        src = std::move(*parsed);
    } else {
        if (leafon.empty() || leafoff.empty())
            return Error{"scene: give a manifest (scene.json) or both --leafon and --leafoff"};
        src.leafon = leafon;
        src.leafoff = leafoff;
        src.elevation = dem;
        src.name = std::filesystem::path(leafon).stem().string();
    }
    return loadScene(src, cache.empty() ? defaultCacheDir() : std::filesystem::path(cache));
}

Result<std::pair<int, int>> parseSize(const std::string& text) {
    const size_t x = text.find_first_of("xX");
    auto bad = [&] { return Error{"size '" + text + "': expected WxH, e.g. 1920x1080 (each 1..16384)"}; };
    if (x == std::string::npos) return bad();
    int w = 0, h = 0;
    auto r1 = std::from_chars(text.data(), text.data() + x, w);
    auto r2 = std::from_chars(text.data() + x + 1, text.data() + text.size(), h);
    if (r1.ec != std::errc() || r1.ptr != text.data() + x || r2.ec != std::errc() ||
        r2.ptr != text.data() + text.size() || w < 1 || h < 1 || w > 16384 || h > 16384)
        return bad();
    return std::pair{w, h};
}

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

Result<gl::ContextInfo> renderStills(const Scene& scene, int width, int height, const std::vector<StillRequest>& stills,
                                     bool windowed) {
    auto ctx = windowed ? gl::createWindowContext(width, height, "seasonview", false) : gl::createHeadlessContext();
    if (!ctx) return ctx.error();
    const int errorsBefore = gl::debugErrorCount();
    auto renderer = ReferenceRendererGL::create(scene);
    if (!renderer) return renderer.error();
    gl::RenderTarget target(width, height);
    for (const StillRequest& s : stills) {
        (*renderer)->render(s.camera, s.season, target);
        std::vector<std::uint8_t> rgba = target.readRgba();
        if (const std::string e = gl::drainErrors(); !e.empty() || gl::debugErrorCount() != errorsBefore)
            return Error{"OpenGL error while rendering " + s.out.string() + (e.empty() ? "" : ": " + e)};
        std::vector<std::uint8_t> rgb(size_t(width) * size_t(height) * 3);
        for (size_t i = 0, n = size_t(width) * size_t(height); i < n; ++i)
            for (int c = 0; c < 3; ++c) rgb[i * 3 + size_t(c)] = rgba[i * 4 + size_t(c)];
        if (auto st = writeImageAtomic(s.out, rgb.data(), width, height, 3); !st) return st.error();
        if (windowed) {
            int fw = 0, fh = 0;
            (*ctx)->framebufferSize(fw, fh);
            target.blitToDefault(fw, fh);
            (*ctx)->swapBuffers();
        }
    }
    return (*ctx)->info();
}

void printSceneNotes(const Scene& scene) {
    for (const auto& w : scene.sources.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
    for (const auto& n : scene.notes) std::fprintf(stderr, "note: %s\n", n.c_str());
}

} // namespace seasonview::app
