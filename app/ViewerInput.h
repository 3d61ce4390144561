#pragma once
// The viewer's input: what the window's callbacks gather between frames, and one frame's input from the window and
// a script (ViewerScript.h) merged, so both go through the same handling.
#include "ViewerScript.h"

#include <glm/vec2.hpp>
#include <nlohmann/json.hpp>

#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

struct GLFWwindow;

namespace seasonview::app {

/// Key names of scripts and the help text ("W", "7", "Space", "Tab", "Shift", "Escape", "Up", ...) -> GLFW key codes;
/// nullopt for a name the viewer does not know.
std::optional<int> keyCode(const std::string& name);

/// Window input gathered by the GLFW callbacks between frames (window pixels, top-left origin). Input the settings
/// panel takes (ImGui wants the mouse or keyboard) is not recorded.
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

/// Points `window`'s cursor, button, scroll and key callbacks at `input`, which must outlive the window's events.
void attachWindowInput(GLFWwindow* window, WindowInput& input);

/// One frame's input: GLFW key codes pressed and held, the cursor, a drag with its button (-1: none) and where a drag
/// started this frame, wheel notches, and the script's `set` events.
struct FrameInput {
    glm::dvec2 cursor{0.0};
    std::vector<int> pressed;
    std::set<int> held;
    glm::dvec2 drag{0.0};
    int dragButton = -1;
    bool dragStarted[2] = {false, false};
    glm::dvec2 dragStart[2] = {glm::dvec2(0.0), glm::dvec2(0.0)};
    double wheel = 0.0;
    std::vector<std::pair<std::string, nlohmann::json>> settings;
};

/// Takes what `window` gathered since the last frame (and resets it), then adds what `script` does in (t0, t1].
/// The script's keys must all be known to keyCode (checked when it is loaded).
FrameInput takeFrameInput(WindowInput& window, const std::vector<ScriptEvent>& script, double t0, double t1);

} // namespace seasonview::app
