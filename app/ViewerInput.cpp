#include "ViewerInput.h"

#ifndef GLFW_INCLUDE_NONE
#define GLFW_INCLUDE_NONE
#endif
#include <GLFW/glfw3.h>
#include <imgui.h>

#include <cctype>
#include <map>

namespace seasonview::app {

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

namespace {

WindowInput* inputOf(GLFWwindow* w) { return static_cast<WindowInput*>(glfwGetWindowUserPointer(w)); }

bool panelWantsMouse() { return ImGui::GetCurrentContext() && ImGui::GetIO().WantCaptureMouse; }

void onCursor(GLFWwindow* w, double x, double y) {
    WindowInput* in = inputOf(w);
    if (panelWantsMouse() && !in->buttons[0] && !in->buttons[1]) {
        in->cursor = {x, y};
        return;
    }
    if (in->buttons[0] || in->buttons[1]) in->drag += glm::dvec2(x, y) - in->cursor;
    in->cursor = {x, y};
}

void onButton(GLFWwindow* w, int button, int action, int) {
    WindowInput* in = inputOf(w);
    if (button > 1) return;
    if (action == GLFW_PRESS && panelWantsMouse()) return;
    in->buttons[button] = action == GLFW_PRESS;
    if (action == GLFW_PRESS) {
        in->pressedButton[button] = true;
        in->pressedAt[button] = in->cursor;
    }
}

void onScroll(GLFWwindow* w, double, double dy) {
    if (panelWantsMouse()) return;
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

} // namespace

void attachWindowInput(GLFWwindow* window, WindowInput& input) {
    glfwSetWindowUserPointer(window, &input);
    glfwSetCursorPosCallback(window, onCursor);
    glfwSetMouseButtonCallback(window, onButton);
    glfwSetScrollCallback(window, onScroll);
    glfwSetKeyCallback(window, onKey);
}

FrameInput takeFrameInput(WindowInput& window, const std::vector<ScriptEvent>& script, double t0, double t1) {
    FrameInput in;
    in.cursor = window.cursor;
    in.pressed = std::move(window.pressedKeys);
    window.pressedKeys.clear();
    in.held = window.held;
    in.drag = window.drag;
    in.dragButton = window.buttons[0] ? 0 : (window.buttons[1] ? 1 : -1);
    for (int b = 0; b < 2; ++b) {
        in.dragStarted[b] = window.pressedButton[b];
        in.dragStart[b] = window.pressedAt[b];
        window.pressedButton[b] = false;
    }
    in.wheel = window.wheel;
    window.drag = {0.0, 0.0};
    window.wheel = 0.0;
    if (script.empty()) return in;
    const ScriptFrame sf = scriptFrame(script, t0, t1);
    for (const std::string& k : sf.pressed) in.pressed.push_back(*keyCode(k));
    for (const std::string& k : sf.held) in.held.insert(*keyCode(k));
    if (sf.cursorSet) in.cursor = sf.cursor;
    if (sf.dragButton >= 0) {
        in.drag += sf.drag;
        in.dragButton = sf.dragButton;
        if (sf.dragStarted) {
            in.dragStarted[sf.dragButton] = true;
            in.dragStart[sf.dragButton] = sf.dragStart;
        }
    }
    in.wheel += sf.wheel;
    in.settings = sf.settings;
    return in;
}

} // namespace seasonview::app
