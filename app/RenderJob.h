#pragma once
// What `render` and `demo` share: turning CLI scene arguments into a Scene, parsing sizes and cameras, and
// rendering stills with the reference renderer through a headless or windowed context.
#include "Camera.h"
#include "ReferenceRendererGL.h"
#include "Scene.h"
#include "gl/GlContext.h"

#include <CLI/CLI.hpp>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace seasonview::app {

/// A scene given as a manifest path or as --leafon/--leafoff/--dem flags.
struct SceneArgs {
    std::string manifest;
    std::string leafon, leafoff, dem;
    std::string cache;
    void addTo(CLI::App& cmd);
    Result<Scene> load() const;
};

/// "WxH" -> width, height (1..16384 each).
Result<std::pair<int, int>> parseSize(const std::string& text);

/// The camera looking straight down at the whole scene (default when --camera is not given).
Camera overviewCamera(const Scene& scene, double aspect);

/// An oblique camera `pitchDeg` below the horizon at heading `yawDeg`, looking at the scene centre from
/// `distanceFraction` × the scene diagonal away (kept at least 20 m above the terrain under it).
Camera obliqueCamera(const Scene& scene, double yawDeg, double pitchDeg, double distanceFraction = 0.55);

/// Checks an output image name before any work: extension .png/.tif/.tiff and an existing folder.
Status checkImageOutput(const std::filesystem::path& out);

struct StillRequest {
    Camera camera;
    Season season = Season::LeafOn;
    std::filesystem::path out;
};

/// Renders each request with one context and one renderer and writes the images atomically. `windowed` renders
/// through a hidden GLFW window instead of EGL (same renderer code). Prints nothing; returns the context info.
Result<gl::ContextInfo> renderStills(const Scene& scene, int width, int height, const std::vector<StillRequest>& stills,
                                     bool windowed);

/// Prints the scene's warnings and notes to stderr, one line each.
void printSceneNotes(const Scene& scene);

} // namespace seasonview::app
