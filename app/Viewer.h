#pragma once
// The interactive viewer behind `seasonview view`: a GLFW window (also under Xvfb) showing the scene through the same
// renderers as `render` and `bench`, a Dear ImGui settings panel with a HUD, navigation (core/camera/CameraControl.h:
// map, fly, orbit), screenshots, camera bookmarks, and recording the flown camera as a bench path. Scripts,
// `--screenshot-at` and `--quit-at` run it without a person (ViewerScript.h).
#include "CameraControl.h"
#include "CityRendererGL.h"
#include "LiveScene.h"
#include "Scene.h"
#include "ViewerRecording.h"
#include "ViewerScript.h"

#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace seasonview::app {

/// Everything the viewer runs with, checked by the command (ViewCommand.cpp) before a window opens.
struct ViewerOptions {
    std::pair<int, int> size{1280, 720};   // window, pixels
    Camera start;                          // the first camera
    std::optional<NavMode> mode;           // nullopt: map when looking straight down, else fly
    ViewerSettings settings;               // the panel's first state
    std::filesystem::path cache;           // pyramids and the city's tree
    int clipSize = 1024, gridSize = 255;   // imagery clipmap N, geometry clipmap n
    int clipLevels = 0;                    // toroidal levels allocated at least (0: as the scene needs)
    std::optional<city::CitySettings> city; // the city model (nullopt: none)
    std::filesystem::path cityTree;         // its atlas tree
    std::vector<ScriptEvent> script;        // timed input (empty: none)
    std::string scriptName;                 // its file, for errors
    std::vector<TimedScreenshot> shots, windowShots; // sorted by time: the view, the whole window
    std::optional<std::pair<int, int>> shotSize;     // P's screenshots (nullopt: the window's size)
    std::filesystem::path screenshotDir{"."};        // P's screenshots
    double quitAt = -1.0;                  // exit at this time (negative: never)
    double fixedDt = 0.0;                  // seconds per frame of the clock (0: real time)
    bool scripted = false;                 // no person: swap without waiting for the display
    std::filesystem::path record;          // R records the flight here (empty: R says so)
    Bookmarks bookmarks;
};

/// Prepares the scene's pyramids, opens the window, runs the viewer until it is closed, Escape, `quitAt` or an
/// error. Returns the exit code; an error is printed as one line ("seasonview view: ...").
int runViewer(const Scene& scene, ViewerOptions options);

} // namespace seasonview::app
